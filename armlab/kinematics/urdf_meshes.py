"""Where a URDF's mesh files are: ``package://`` and relative names resolved on disk.

A URDF published with a ROS package names its meshes ``package://NAME/meshes/x.stl``.
Without ROS installed the lab looks for the package folder ``NAME`` in this order:

1. the URDF's own folder and each of its parents: a folder *called* ``NAME`` on that
   path (the URDF inside its package, e.g. ``NAME/urdf/arm.urdf``), or a folder
   ``NAME`` *inside* one of them (packages checked out side by side);
2. each folder given as a package path (``--package-path DIR``): ``DIR/NAME``, or
   ``DIR`` itself when it is called ``NAME``.

A name that cannot be found is warned about once (per URDF and name), naming it;
the viewer then draws that link from its collision geometry or as a capsule.
"""

from __future__ import annotations

import warnings
from pathlib import Path

_warned: set[tuple[str, str]] = set()


class MissingMeshWarning(UserWarning):
    """A mesh named in a URDF is not on disk; the link is drawn without it."""


def _package_roots(name: str, urdf_path: Path, package_paths: tuple[Path, ...]) -> list[Path]:
    roots: list[Path] = []
    for folder in [urdf_path.resolve().parent, *urdf_path.resolve().parents]:
        if folder.name == name:
            roots.append(folder)
        roots.append(folder / name)
    for folder in package_paths:
        folder = Path(folder).expanduser().resolve()
        roots.append(folder if folder.name == name else folder / name)
    return roots


def resolve_resource(filename: str, *, urdf_path: str | Path,
                     package_paths: tuple[str | Path, ...] = ()) -> Path | None:
    """The file a URDF ``filename`` attribute names, or None when it is not on disk.

    Handles ``package://NAME/rest``, ``file://`` and names relative to the URDF's folder.
    """
    urdf_path = Path(urdf_path)
    paths = tuple(Path(p) for p in package_paths)
    if filename.startswith("package://"):
        name, _, rest = filename[len("package://"):].partition("/")
        candidates = [root / rest for root in _package_roots(name, urdf_path, paths)]
    elif filename.startswith("file://"):
        candidates = [Path(filename[len("file://"):])]
    else:
        candidates = [urdf_path.resolve().parent / filename]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    return None


def warn_missing_once(filename: str, *, urdf_path: str | Path, link: str) -> None:
    """Warn (once per URDF and file name) that ``filename`` of ``link`` cannot be found."""
    key = (str(Path(urdf_path).resolve()), filename)
    if key in _warned:
        return
    _warned.add(key)
    warnings.warn(f"{urdf_path}: mesh {filename!r} of link {link!r} not found (looked in the "
                  "URDF's folder, its parents and --package-path); drawing the link from its "
                  "collision geometry or as a capsule", MissingMeshWarning, stacklevel=2)
