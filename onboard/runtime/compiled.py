"""Numeric hot loops compiled with numba, and where the compiled code is kept.

A few loops of plain float arithmetic dominate their tasks when the interpreter runs them: the
bogie model's substeps (:mod:`onboard.plant.bogie_kernel`), the energy planner's forward and
coasting integrations (:mod:`onboard.adf.odp_energy`). :func:`compiled` turns such a function
into numba's nopython-mode function, compiled on first call and cached on disk, so that a
process after the first loads it in a fraction of a second instead of compiling it for
several. The arithmetic is the interpreter's, operation for operation: numba compiles without
fast-math, so no reordering and no fused multiply-add (the tests check the bits where a
function has an interpreted twin). With ``NUMBA_DISABLE_JIT=1`` the same functions run in the
interpreter, for debugging.

numba judges a cached function stale by the time stamp of the file that defines it only;
compiled code also inlines the functions it calls and freezes the module constants it reads,
which may live in other files. The cache therefore lives under the digest of the defining
file and of the modules named as dependencies (:func:`cache_directory`): a change to any of
them compiles afresh.
"""

from __future__ import annotations

import functools
import hashlib
import os
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar, cast

import numba

__all__ = ["cache_directory", "compiled", "interpreted"]

_Function = TypeVar("_Function", bound=Callable[..., object])
_config: Any = numba.config
"""numba's settings, read from the environment when numba is imported (untyped)."""


@functools.cache
def cache_directory(*source_files: str) -> str:
    """numba's cache directory (``NUMBA_CACHE_DIR``, by default ``$XDG_CACHE_HOME/ato/numba``)
    under 16 hex digits of the digest of ``source_files``, in their order."""
    digest = hashlib.sha256()
    for source_file in source_files:
        digest.update(Path(source_file).read_bytes())
    cache_home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    base = _config.CACHE_DIR or os.path.join(cache_home, "ato", "numba")
    return os.path.join(base, digest.hexdigest()[:16])


def compiled(*dependencies: ModuleType) -> Callable[[_Function], _Function]:
    """A decorator: the function compiled in nopython mode on first call, cached under the
    digest of its own module's source and of ``dependencies``' (the modules whose functions it
    calls or whose constants it reads)."""

    def decorate(function: _Function) -> _Function:
        files = (function.__code__.co_filename, *(str(m.__file__) for m in dependencies))
        previous = _config.CACHE_DIR
        _config.CACHE_DIR = cache_directory(*files)  # numba reads it when it decorates
        try:
            return cast(_Function, numba.njit(cache=True)(function))
        except RuntimeError:  # no writable place for a cache: compiled in each process
            return cast(_Function, numba.njit(function))
        finally:
            _config.CACHE_DIR = previous

    return decorate


def interpreted(function: _Function) -> _Function:
    """The Python function a :func:`compiled` one was made from (itself when numba's JIT is
    disabled), to run its source in the interpreter: the tests compare the two."""
    return cast(_Function, getattr(function, "py_func", function))
