"""Side by side with a git ref (issue 24): the reference's work tree, its interpreter, and the
order of the runs.

``ato bench run --against REF`` and ``ato bench adf --against REF`` measure the current tree
and a git ref on one machine in one sitting, so that a speed-up is a ratio measured side by
side and not two figures from two days. Both sides run in fresh interpreters of their own, the
same way:

- the **tree** is the code this module belongs to (the working tree as it is, uncommitted
  changes included), run by the current interpreter;
- the **ref** is checked out by :func:`reference_side` into a temporary detached work tree
  (``git worktree add --detach``) and run with its root first on ``PYTHONPATH`` and as the
  working directory, by :func:`interpreter_for`'s choice: the current interpreter when the
  ref's dependencies (``requires-python`` and ``[project].dependencies``) equal the tree's,
  otherwise a virtual environment built for them once and cached under
  ``.ato/bench-envs/<hash of the dependencies>``. The work tree is removed on leaving, also on an
  error, Ctrl-C or SIGTERM.

:func:`interleaved` fixes the order: round after round, each item on the tree and then on the
ref, so that whatever else the machine does drifts over both sides alike.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import tomllib
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any, Literal

from rich.console import Console

from deploy._exceptions import DeployError

__all__ = [
    "ENVIRONMENTS_DIR",
    "REPOSITORY_ROOT",
    "SIDES",
    "ReferenceTreeError",
    "Side",
    "SideLabel",
    "build_environment",
    "interleaved",
    "interpreter_for",
    "reference_side",
    "reference_work_tree",
    "resolve_commit",
    "runtime_dependencies",
    "tree_over_ref",
    "tree_side",
    "write_json",
]

REPOSITORY_ROOT = Path(__file__).resolve().parents[2]
"""The current tree: the root of the code this module belongs to."""
ENVIRONMENTS_DIR = REPOSITORY_ROOT / ".ato" / "bench-envs"
"""Where environments built for refs whose dependencies differ from the tree's are kept."""
SideLabel = Literal["tree", "ref"]
SIDES: tuple[SideLabel, SideLabel] = ("tree", "ref")
_COMPLETE_MARK = "ato-bench-env-complete"


class ReferenceTreeError(DeployError, RuntimeError):
    """The ref cannot be measured: not a commit, no work tree, or no environment for it."""


@dataclass(frozen=True)
class Side:
    """Where one side's code lives and the interpreter that runs it."""

    label: SideLabel
    root: Path
    python: Path
    description: str
    """The commit, as the report prints it (the tree's says when it has uncommitted changes)."""

    def environment(self) -> dict[str, str]:
        """The process environment of this side's runs: its root first on ``PYTHONPATH``."""
        environment = dict(os.environ)
        paths = [str(self.root), *filter(None, [environment.get("PYTHONPATH")])]
        environment["PYTHONPATH"] = os.pathsep.join(paths)
        return environment


def interleaved(items: Sequence[str], runs: int) -> list[tuple[int, str, SideLabel]]:
    """The order of the runs: ``(round, item, side)``, rounds outermost, the tree before the
    ref for each item (tree, ref, tree, ref, ...)."""
    return [(index, item, side) for index in range(runs) for item in items for side in SIDES]


def tree_over_ref(tree: float | None, ref: float | None) -> float | None:
    """The ratio of a figure, tree over ref; None when either is missing or the ref's is 0."""
    return None if tree is None or not ref else tree / ref


def _git(repository: Path, *arguments: str) -> str:
    try:
        finished = subprocess.run(
            ["git", "-C", str(repository), *arguments],
            capture_output=True,
            text=True,
            check=False,
        )
    except OSError as exc:
        raise ReferenceTreeError(f"git could not be run: {exc}") from exc
    if finished.returncode != 0:
        reason = finished.stderr.strip().splitlines()
        raise ReferenceTreeError(
            f"git {' '.join(arguments)} failed: {reason[-1] if reason else finished.returncode}"
        )
    return finished.stdout.strip()


def resolve_commit(ref: str, *, repository: Path = REPOSITORY_ROOT) -> str:
    """The full hash of the commit ``ref`` names in ``repository``."""
    if not ref or ref.startswith("-"):
        raise ReferenceTreeError(f"{ref!r} is not a git ref")
    try:
        return _git(repository, "rev-parse", "--verify", "--quiet", f"{ref}^{{commit}}")
    except ReferenceTreeError as exc:
        raise ReferenceTreeError(f"{ref!r} names no commit of {repository}") from exc


@contextmanager
def _terminate_as_exit() -> Iterator[None]:
    """SIGTERM unwinds like Ctrl-C (so that ``finally`` clean-ups run); main thread only."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def leave(signum: int, _frame: FrameType | None) -> None:
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, leave)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def reference_work_tree(ref: str, *, repository: Path = REPOSITORY_ROOT) -> Iterator[Path]:
    """``ref`` checked out, detached, into a temporary work tree of ``repository``; removed
    (with git's record of it) on leaving, whatever the way out."""
    commit = resolve_commit(ref, repository=repository)
    parent = Path(tempfile.mkdtemp(prefix="ato-bench-ref-"))
    work_tree = parent / "tree"
    with _terminate_as_exit():
        try:
            _git(repository, "worktree", "add", "--detach", "--quiet", str(work_tree), commit)
            yield work_tree
        finally:
            _remove_work_tree(repository, work_tree)
            shutil.rmtree(parent, ignore_errors=True)


def _remove_work_tree(repository: Path, work_tree: Path) -> None:
    try:
        _git(repository, "worktree", "remove", "--force", str(work_tree))
    except ReferenceTreeError:
        # Never added, or git refused: delete the files and let git forget the entry.
        shutil.rmtree(work_tree, ignore_errors=True)
        with suppress(ReferenceTreeError):
            _git(repository, "worktree", "prune")


def runtime_dependencies(pyproject: Path) -> dict[str, Any]:
    """What a run needs installed: ``requires-python`` and ``[project].dependencies`` (sorted;
    the test extras and the tools' settings do not change a run)."""
    try:
        project = tomllib.loads(pyproject.read_text(encoding="utf-8")).get("project", {})
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ReferenceTreeError(f"{pyproject} cannot be read: {exc}") from exc
    return {
        "requires-python": project.get("requires-python", ""),
        "dependencies": sorted(project.get("dependencies", [])),
    }


def _dependency_key(dependencies: dict[str, Any]) -> str:
    text = json.dumps(dependencies, sort_keys=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def build_environment(directory: Path, requirements: Sequence[str]) -> Path:
    """A virtual environment in ``directory`` with ``requirements`` installed (pip, from the
    configured indexes); its interpreter. One built before is reused; one whose build did not
    finish is built again, and a failed or interrupted build leaves nothing behind."""
    python = directory / "bin" / "python"
    if (directory / _COMPLETE_MARK).is_file() and python.exists():
        return python
    shutil.rmtree(directory, ignore_errors=True)
    directory.parent.mkdir(parents=True, exist_ok=True)
    steps = [[sys.executable, "-m", "venv", str(directory)]]
    if requirements:
        steps.append([str(python), "-m", "pip", "install", "--quiet", *requirements])
    try:
        for command in steps:
            finished = subprocess.run(command, capture_output=True, text=True, check=False)
            if finished.returncode != 0:
                lines = finished.stderr.strip().splitlines()
                raise ReferenceTreeError(
                    f"the environment {directory} could not be built: "
                    f"{lines[-1] if lines else f'exit {finished.returncode}'}"
                )
        (directory / _COMPLETE_MARK).write_text(json.dumps(list(requirements)), encoding="utf-8")
    except BaseException:
        shutil.rmtree(directory, ignore_errors=True)
        raise
    return python


def interpreter_for(
    work_tree: Path,
    *,
    tree_root: Path = REPOSITORY_ROOT,
    environments: Path = ENVIRONMENTS_DIR,
    console: Console | None = None,
) -> Path:
    """The interpreter to run ``work_tree``'s code: the current one when its runtime
    dependencies equal ``tree_root``'s, otherwise an environment built for them (cached by
    their hash under ``environments``)."""
    theirs = runtime_dependencies(work_tree / "pyproject.toml")
    if theirs == runtime_dependencies(tree_root / "pyproject.toml"):
        return Path(sys.executable)
    directory = environments / _dependency_key(theirs)
    if console is not None and not (directory / _COMPLETE_MARK).is_file():
        console.print(f"the ref's dependencies differ from the tree's: building {directory}…")
    return build_environment(directory, theirs["dependencies"])


def _tree_description(repository: Path) -> str:
    commit = _git(repository, "rev-parse", "--short=12", "HEAD")
    changed = _git(repository, "status", "--porcelain", "--untracked-files=no")
    return f"{commit} + uncommitted changes" if changed else commit


def tree_side(repository: Path = REPOSITORY_ROOT) -> Side:
    """The current tree, run by the current interpreter."""
    return Side("tree", repository, Path(sys.executable), _tree_description(repository))


@contextmanager
def reference_side(
    ref: str,
    *,
    repository: Path = REPOSITORY_ROOT,
    environments: Path = ENVIRONMENTS_DIR,
    console: Console | None = None,
) -> Iterator[Side]:
    """The ref's side: its work tree and interpreter, for the time of the ``with`` block."""
    with reference_work_tree(ref, repository=repository) as work_tree:
        python = interpreter_for(
            work_tree, tree_root=repository, environments=environments, console=console
        )
        commit = _git(work_tree, "rev-parse", "--short=12", "HEAD")
        yield Side("ref", work_tree, python, f"{ref} = {commit}")


def _strict(value: Any) -> Any:
    """``value`` with NaN and infinities as null, so that the file is strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _strict(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_strict(item) for item in value]
    return value


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write a bench's numbers to ``path`` as strict JSON (NaN as null), whole or not at all."""
    text = json.dumps(_strict(data), indent=2, allow_nan=False) + "\n"
    partial = path.with_name(f".{path.name}.partial")
    partial.write_text(text, encoding="utf-8")
    partial.replace(path)
