"""What produced a run's result, as hashes that ``--resume`` compares and that name the
system under test in ``compare`` and the history (:mod:`reports.identity`).

A run is reproduced by its scenario (the content hash, :mod:`suite.run.info`), the code
that simulated and judged it, and its controller. Two hashes stand for the code, kept in
``RunInfo.scenario_spec`` beside the content hash:

* ``code_sha256`` (:data:`CODE_KEY`): SHA-256 over the path and bytes of every ``.py``
  file of hwyeval's packages (``suite``, ``controllers``, ``reports``, ``sumo_nets``),
  as they are on disk: a commit, an uncommitted edit and an installed release each
  give their own.
* ``controller_sha256`` (:data:`CONTROLLER_KEY`): the controller's own code. For a
  plug-in controller, the same over the source of the package (or the lone module) that
  defines its factory, plus the distribution's name and version for an entry point:
  editing one line of a ``--plugin`` file changes it. For a built-in one, over the
  ``controllers`` package (every built-in controller, its behaviour layer, plant model
  and parameter defaults live there; a change to the reports or the simulation loop
  is not a change of the controller).

The controller's options are in the content hash already; its resolved parameters
follow from the options and the two hashes.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import sys
from collections.abc import Iterable
from pathlib import Path

from controllers import registry
from reports.identity import CODE_KEY, CONTROLLER_KEY

PACKAGES = ("suite", "controllers", "reports", "sumo_nets")

__all__ = ["CODE_KEY", "CONTROLLER_KEY", "builtin_controllers_sha256", "controller_sha256",
           "hwyeval_code_sha256"]


def _hash_files(root: Path, files: Iterable[Path], extra: str = "") -> str:
    digest = hashlib.sha256(extra.encode())
    for path in sorted(files):
        digest.update(str(path.relative_to(root)).encode() + b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()


def _package_files(root: Path, packages: Iterable[str]) -> list[Path]:
    return [f for pkg in packages for f in (root / pkg).rglob("*.py")
            if "__pycache__" not in f.parts]


@functools.cache
def hwyeval_code_sha256() -> str:
    """The hash of hwyeval's own sources (module doc), computed once per process."""
    root = Path(__file__).resolve().parents[2]
    return _hash_files(root, _package_files(root, PACKAGES))


@functools.cache
def builtin_controllers_sha256() -> str:
    """The hash of the ``controllers`` package's sources (the built-in controllers'
    code, module doc), computed once per process."""
    root = Path(__file__).resolve().parents[2]
    return _hash_files(root, _package_files(root, ("controllers",)), extra="built in\0")


def _module_files(module_name: str) -> tuple[Path, list[Path]]:
    """(root, the .py files) of the top-level package holding ``module_name``, or of the
    module alone when it is not in a package."""
    top = module_name.split(".")[0]
    module = sys.modules.get(top)
    file = getattr(module, "__file__", None) if module is not None else None
    if file is None:
        spec = importlib.util.find_spec(top)
        file = spec.origin if spec is not None else None
    if file is None:
        return Path("."), []
    path = Path(file).resolve()
    if path.name == "__init__.py":
        pkg = path.parent
        return pkg.parent, [f for f in pkg.rglob("*.py") if "__pycache__" not in f.parts]
    return path.parent, [path]


def controller_sha256(name: str) -> str:
    """The hash of controller ``name``'s code (module doc): its plug-in source, or the
    built-in controllers' package."""
    origin = registry.origin(name)
    if origin == "built in":
        return builtin_controllers_sha256()
    module_name = registry.factory_module(name)
    root, files = _module_files(module_name)
    return _hash_files(root, files, extra=f"{origin}\0{module_name}\0")
