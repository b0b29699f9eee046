"""Robot packages (a folder or a zip of URDF/MJCF, meshes and a sidecar), opened safely.

A zip is checked whole before anything is extracted: no absolute path, no ``..`` component, no
drive letter, no symbolic link, at most ``MAX_FILES`` members and ``MAX_BYTES`` unpacked. Files
are only ever written inside the folder the caller names. ``resolve_mesh`` turns a URDF mesh
reference (``package://NAME/...``, ``file://...`` or a relative path) into a file, optionally
confined to a set of folders.
"""

from __future__ import annotations

import shutil
import stat
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, NoReturn

from app.errors import one_line, storage_problem
from app.planning.robots._types import RobotError

__all__ = [
    "MAX_BYTES",
    "MAX_FILES",
    "RobotPackage",
    "check_mjcf_files",
    "open_robot_package",
    "resolve_mesh",
]

MAX_FILES = 5_000
MAX_BYTES = 1 << 30  # 1 GiB unpacked
_MODEL_SUFFIXES = (".urdf", ".xml", ".mjcf")


@dataclass(frozen=True)
class RobotPackage:
    """An opened robot package.

    Attributes:
        root: the folder holding the package's files.
        urdfs: URDF files inside it, sorted.
        mjcfs: MJCF (``.xml``/``.mjcf``) files inside it, sorted.
        sidecars: ``.yaml``/``.yml`` files inside it, sorted.
        package_dirs: folders for ``package://`` lookups: the root and every folder under it
            holding a ``package.xml`` (a ROS package) or named like a ``package://`` target.
    """

    root: Path
    urdfs: tuple[Path, ...]
    mjcfs: tuple[Path, ...]
    sidecars: tuple[Path, ...]
    package_dirs: tuple[Path, ...]

    def only_urdf(self) -> Path:
        """The package's one URDF, or a RobotError listing what it holds."""
        if len(self.urdfs) != 1:
            names = [str(p.relative_to(self.root)) for p in self.urdfs]
            raise RobotError(
                f"{self.root.name}: {len(self.urdfs)} URDF files {names}: expected exactly one "
                "(name the one to load)"
            )
        return self.urdfs[0]


def _check_member(archive: str, info: zipfile.ZipInfo) -> PurePosixPath:
    name = info.filename
    path = PurePosixPath(name.replace("\\", "/"))
    mode = info.external_attr >> 16
    drive = bool(path.parts) and ":" in path.parts[0]
    if path.is_absolute() or drive:
        raise RobotError(
            f"{archive}: member '{name}' has an absolute path: expected relative paths"
        )
    if any(part == ".." for part in path.parts):
        raise RobotError(f"{archive}: member '{name}' points outside the archive ('..'): refused")
    if stat.S_ISLNK(mode):
        raise RobotError(f"{archive}: member '{name}' is a symbolic link: expected plain files")
    return path


def _extract_zip(source: Path, dest: Path) -> None:
    try:
        archive = zipfile.ZipFile(source)
    except (zipfile.BadZipFile, OSError) as exc:
        raise RobotError(
            f"{source.name}: not a readable zip archive ({exc}): expected a .zip"
        ) from None
    with archive:
        members = archive.infolist()
        if len(members) > MAX_FILES:
            raise RobotError(
                f"{source.name}: {len(members)} members: expected at most {MAX_FILES} files"
            )
        paths = [_check_member(source.name, info) for info in members]
        total = sum(info.file_size for info in members)
        if total > MAX_BYTES:
            raise RobotError(
                f"{source.name}: unpacks to {total} bytes: expected at most {MAX_BYTES} bytes"
            )
        dest.mkdir(parents=True, exist_ok=True)
        root = dest.resolve()
        for info, path in zip(members, paths, strict=True):
            target = (root / Path(*path.parts)).resolve() if path.parts else root
            if not target.is_relative_to(root):  # belt and braces after the name checks
                raise RobotError(f"{source.name}: member '{info.filename}' escapes the folder")
            if info.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            _extract_member(archive, info, target, source.name)


#: What a hostile or damaged member raises while it is written out: a name the file system
#: cannot hold, a file where a folder must go, a corrupt or unsupported compressed stream.
_EXTRACT_ERRORS = (OSError, zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError)


def _extract_member(
    archive: zipfile.ZipFile, info: zipfile.ZipInfo, target: Path, name: str
) -> None:
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with archive.open(info) as src, open(target, "wb") as out:
            shutil.copyfileobj(src, out)
    except _EXTRACT_ERRORS as exc:
        if storage_problem(exc) is not None:
            raise  # a full or read-only disk is the server's problem, not the upload's
        member = one_line(info.filename, 80)
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise RobotError(
            f"{name}: member '{member}' cannot be extracted ({reason}): expected a zip of a"
            " robot's folder"
        ) from None


def _package_dirs(root: Path) -> tuple[Path, ...]:
    found = [root]
    for marker in sorted(root.rglob("package.xml")):
        found.append(marker.parent.parent)
    return tuple(dict.fromkeys(found))


def open_robot_package(source: str | Path, dest: str | Path | None = None) -> RobotPackage:
    """Open a robot folder, or extract a robot zip into ``dest`` and open that.

    Args:
        source: a folder, or a ``.zip`` file.
        dest: folder to extract a zip into (created; required for a zip). Nothing is written
            anywhere else, and nothing at all when the zip is refused.

    Raises:
        RobotError: a missing source, a zip that is not one, or a member with an absolute
            path, a ``..`` component or a link, too many files or too many bytes.
    """
    path = Path(source)
    if path.is_dir():
        root = path.resolve()
    elif path.is_file() and zipfile.is_zipfile(path):
        if dest is None:
            raise RobotError(f"{path.name}: a zip needs a folder to extract into: expected dest")
        _extract_zip(path, Path(dest))
        root = Path(dest).resolve()
    elif path.exists():
        raise RobotError(f"{path.name}: neither a folder nor a zip archive: expected one of them")
    else:
        raise RobotError(f"{path.name}: no such file or folder ({path})")
    files = sorted(p for p in root.rglob("*") if p.is_file())
    return RobotPackage(
        root=root,
        urdfs=tuple(p for p in files if p.suffix.lower() == ".urdf"),
        mjcfs=tuple(p for p in files if p.suffix.lower() in _MODEL_SUFFIXES[1:]),
        sidecars=tuple(p for p in files if p.suffix.lower() in (".yaml", ".yml")),
        package_dirs=_package_dirs(root),
    )


def resolve_mesh(
    reference: str,
    *,
    base_dir: Path | None,
    package_dirs: Sequence[Path] = (),
    allowed_roots: Sequence[Path] | None = None,
) -> Path | None:
    """The file a URDF mesh reference names, or None when it cannot be found (or is refused).

    Args:
        reference: ``package://NAME/rest``, ``file:///abs/path`` or a path relative to the URDF.
        base_dir: the URDF's folder (None for URDF text with no file).
        package_dirs: folders holding packages: ``package://NAME/rest`` is ``DIR/NAME/rest``;
            the URDF's own ancestors are tried too (``.../NAME/urdf/robot.urdf``).
        allowed_roots: when given, a resolved file outside all of them is refused (None).
    """
    candidates: list[Path] = []
    if reference.startswith("package://"):
        name, _, rest = reference[len("package://") :].partition("/")
        for folder in package_dirs:
            candidates.append(Path(folder) / name / rest)
        if base_dir is not None:
            for ancestor in (base_dir, *base_dir.parents):
                if ancestor.name == name:
                    candidates.append(ancestor / rest)
    elif reference.startswith("file://"):
        candidates.append(Path(reference[len("file://") :]))
    elif base_dir is not None:
        candidates.append(base_dir / reference)
    roots = None if allowed_roots is None else [Path(r).resolve() for r in allowed_roots]
    for candidate in candidates:
        resolved = candidate.resolve()
        if not resolved.is_file():
            continue
        if roots is not None and not any(resolved.is_relative_to(r) for r in roots):
            continue
        return resolved
    return None


#: MJCF elements whose ``file`` attribute names an asset, with the compiler attribute giving
#: its folder (``assetdir`` stands in for both when the specific one is not set).
_MJCF_ASSET_DIRS = {
    "mesh": "meshdir",
    "skin": "meshdir",
    "texture": "texturedir",
    "hfield": "meshdir",
}


def _inside(folder: PurePosixPath, value: str) -> PurePosixPath | None:
    """``folder / value`` normalised, or None when it is absolute or climbs out of the root
    (``folder`` is relative to the root). Pure path arithmetic: nothing is opened."""
    text = value.replace("\\", "/")
    if text.startswith("/") or (len(text) > 1 and text[1] == ":") or "://" in text:
        return None
    parts: list[str] = []
    for part in (*folder.parts, *PurePosixPath(text).parts):
        if part == "..":
            if not parts:
                return None
            parts.pop()
        elif part != ".":
            parts.append(part)
    return PurePosixPath(*parts)


def check_mjcf_files(mjcf: Path, root: Path) -> None:
    """Refuse an uploaded MJCF whose ``<include>`` or asset files lie outside its upload.

    MuJoCo would open any path the file names (``<include file="/etc/passwd"/>`` was read, and
    whether a file exists could be told from the error). Every ``file`` attribute and the
    compiler's ``meshdir``/``texturedir``/``assetdir`` must be relative paths that stay inside
    ``root``; this is decided from the text alone, so the message is the same whether such a
    file exists or not. Included files inside the upload are checked the same way.

    Raises:
        RobotError: names the file, the element and the attribute.
    """
    import xml.etree.ElementTree as ET

    root = root.resolve()
    pending, seen = [mjcf.resolve()], set()
    while pending:
        path = pending.pop()
        if path in seen or not path.is_file():
            continue  # a missing include inside the upload: MuJoCo says so itself
        seen.add(path)
        rel = PurePosixPath(path.parent.relative_to(root).as_posix())
        try:
            tree = ET.parse(path)
        except ET.ParseError:
            continue  # MuJoCo reports the syntax error with its line
        dirs = {"meshdir": rel, "texturedir": rel}
        for compiler in tree.iter("compiler"):
            for attr in ("assetdir", "meshdir", "texturedir"):
                value = compiler.get(attr)
                if value is None:
                    continue
                inside = _inside(rel, value)
                if inside is None:
                    _refuse(mjcf, "compiler", attr, value)
                for key in ("meshdir", "texturedir") if attr == "assetdir" else (attr,):
                    dirs[key] = inside
        copies = _replicated(tree.getroot(), 1)
        if copies > MAX_REPLICATED:
            raise RobotError(
                f"{mjcf.name}: its <replicate> elements make {copies} copies in all: expected "
                f"at most {MAX_REPLICATED} (a robot arm needs none; nested replicates multiply)"
            )
        for element in tree.iter():
            value = element.get("file")
            if value is None or not isinstance(element.tag, str):
                continue
            folder = dirs.get(_MJCF_ASSET_DIRS.get(element.tag, ""), rel)
            inside = _inside(folder if element.tag != "include" else rel, value)
            if inside is None:
                _refuse(mjcf, element.tag, "file", value)
            elif element.tag == "include":
                pending.append(root / inside)


#: Copies all ``<replicate>`` elements of an uploaded MJCF may make together: nested ones
#: multiply, and a 1.8 KB file of them took 7.5 GB and two minutes to compile.
MAX_REPLICATED = 1000


def _replicated(element: Any, factor: int) -> int:
    """Copies the ``<replicate>`` elements under ``element`` make, each counted with the
    product of the counts around it (``factor``). Stops counting once over the limit."""
    total = 0
    for child in element:
        inner = factor
        if child.tag == "replicate":
            try:
                inner = factor * max(int(child.get("count", "1")), 1)
            except ValueError:
                inner = factor  # MuJoCo reports the bad count itself
            total += inner
        if total > MAX_REPLICATED or inner > MAX_REPLICATED:
            return max(total, inner)
        total += _replicated(child, inner)
    return total


def _refuse(mjcf: Path, tag: str, attr: str, value: str) -> NoReturn:
    raise RobotError(
        f'{mjcf.name}: <{tag} {attr}="{one_line(value, 80)}">: a path outside the uploaded '
        "robot's files: expected a relative path inside the upload (a zip holds the included "
        "files and meshes)"
    )
