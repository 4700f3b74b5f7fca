"""``onboard.sfa`` re-exports its public names through a complete, sorted ``__all__``."""

from __future__ import annotations

import importlib
import pkgutil

import onboard.sfa


def test_all_is_sorted_and_every_name_resolves() -> None:
    names = onboard.sfa.__all__
    assert list(names) == sorted(names)
    for name in names:
        assert getattr(onboard.sfa, name) is not None


def test_every_public_class_of_the_submodules_is_reachable() -> None:
    exported = {id(getattr(onboard.sfa, name)) for name in onboard.sfa.__all__}
    modules = {
        "filter",
        "link",
        "listener",
        "localisation",
        "lockstep",
        "recording",
        "reorder",
        "status",
        "time_base",
    }
    for info in pkgutil.iter_modules(onboard.sfa.__path__):
        if info.name not in modules:
            continue
        module = importlib.import_module(f"onboard.sfa.{info.name}")
        for name in module.__all__:
            value = getattr(module, name)
            if isinstance(value, type):
                assert id(value) in exported, f"onboard.sfa.{info.name}.{name}"
