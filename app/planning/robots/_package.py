"""Robot packages (a folder or a zip of URDF/MJCF, meshes and a sidecar), opened safely.

A zip is checked whole before anything is extracted: no absolute path, no ``..`` component, no
drive letter, no symbolic link, at most ``MAX_FILES`` members and ``MAX_BYTES`` unpacked. Files
are only ever written inside the folder the caller names. ``resolve_mesh`` turns a URDF mesh
reference (``package://NAME/...``, ``file://...`` or a relative path) into a file, optionally
confined to a set of folders.

Meshes are checked before anything parses them (``check_mesh``, ``MeshLimits``): a 0.87 MB zip
held a 300 MB STL that took 45 s and 3 GB to draw. A binary STL's header states its triangle
count, which must match its size; ASCII STL, OBJ, COLLADA and PLY files have their faces
counted from the text; any other mesh is bounded by its size alone.
"""

from __future__ import annotations

import io
import re
import shutil
import stat
import struct
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import IO, Any, NoReturn

from app.errors import one_line, storage_problem
from app.planning.robots._types import RobotError

__all__ = [
    "MAX_BYTES",
    "MAX_FILES",
    "MESH_SUFFIXES",
    "MJCF_FILE_ATTRIBUTES",
    "MeshLimitError",
    "MeshLimits",
    "RobotPackage",
    "check_mesh",
    "check_mjcf_files",
    "check_package_zip",
    "mesh_problem",
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


#: Suffixes of files read as meshes (trimesh for the viewer, assimp for collision checks,
#: MuJoCo for simulation): every package member with one is checked against ``MeshLimits``.
MESH_SUFFIXES = (
    ".stl", ".obj", ".dae", ".ply", ".off", ".glb", ".gltf", ".3mf", ".msh", ".skn", ".fbx",
    ".3ds", ".blend", ".wrl", ".x3d", ".ctm", ".vtk",
)  # fmt: skip


@dataclass(frozen=True)
class MeshLimits:
    """Caps on one mesh and on a package in all.

    The defaults pass every mesh of example-robot-data (the largest, a 29 MB COLLADA file);
    the server takes its own from ``BIOPLAN_MAX_MESH_MB``, ``BIOPLAN_MAX_MESH_TRIANGLES`` and
    ``BIOPLAN_MAX_ROBOT_UNPACKED_MB``.

    Attributes:
        max_bytes: largest mesh file, decoded [bytes].
        max_triangles: most triangles (faces) in one mesh.
        max_unpacked: most bytes a package may unpack to in all.
    """

    max_bytes: int = 64 << 20
    max_triangles: int = 2_000_000
    max_unpacked: int = MAX_BYTES


class MeshLimitError(RobotError):
    """A mesh or a package past a ``MeshLimits`` cap.

    Attributes:
        limit: the cap: ``"max_bytes"``, ``"max_triangles"`` or ``"max_unpacked"``.
    """

    def __init__(self, message: str, limit: str) -> None:
        super().__init__(message)
        self.limit = limit

    def __reduce__(self) -> tuple[Any, ...]:  # pickled back from the parse sandbox whole
        return (type(self), (str(self), self.limit))


_CHUNK = 1 << 20
#: Longest text one pattern below can match [bytes]: a match starting this far before the end
#: of what was read is whole, so counting across chunks neither loses nor repeats one.
_TAIL = 512
#: What starts a face: an ASCII STL facet's end, an OBJ face line (after a newline).
_ASCII_FACET = (b"endfacet",)
_OBJ_FACE = (b"\nf ", b"\nf\t")
_DAE_PRIMITIVE = re.compile(
    rb"<(?:triangles|polylist|polygons|tristrips|trifans)\b[^>]{0,300}?"
    rb"\bcount\s*=\s*[\"']\s*([^\"'<>]{0,40})"
)


def _count(
    handle: IO[bytes],
    pattern: re.Pattern[bytes],
    limit: int,
    value: Callable[[re.Match[bytes]], int] | None = None,
) -> int:
    """Matches of ``pattern`` in the rest of ``handle`` (each counted as ``value(match)``, or
    1), read a chunk at a time; stops once past ``limit``."""
    total, carry = 0, b""
    while True:
        chunk = handle.read(_CHUNK)
        buffer = carry + chunk
        cut = max(len(buffer) - _TAIL, 0) if chunk else len(buffer)
        for match in pattern.finditer(buffer):
            if match.start() >= cut:
                break
            total += 1 if value is None else value(match)
        if not chunk or total > limit:
            return total
        carry = buffer[cut:]


def _count_tokens(
    handle: IO[bytes], tokens: tuple[bytes, ...], limit: int, start: bytes = b""
) -> int:
    """Occurrences of ``tokens`` in ``start`` and the rest of ``handle`` (a newline assumed
    before them), read a chunk at a time at C speed; stops once past ``limit``."""
    total, keep = 0, max(len(t) for t in tokens) - 1
    buffer = b"\n" + start + handle.read(_CHUNK)
    while True:
        total += sum(buffer.count(token) for token in tokens)
        chunk = handle.read(_CHUNK) if total <= limit else b""
        if not chunk:
            return total
        buffer = buffer[-keep:] + chunk  # the kept tail is shorter than any token


def _dae_count(match: re.Match[bytes]) -> int:
    text = match.group(1).strip()
    return int(text) if text.isdigit() else 0  # 40 digits at most: huge, never slow


def _stl_triangles(handle: IO[bytes], size: int, limit: int) -> int | str:
    head = handle.read(84)
    declared = struct.unpack("<I", head[80:84])[0] if len(head) == 84 else -1
    if declared >= 0 and 84 + 50 * declared == size:
        return declared  # a binary STL: its header states the count, its size agrees
    if head.lstrip().startswith(b"solid"):
        return _count_tokens(handle, _ASCII_FACET, limit, start=head)
    if declared < 0:
        return f"an STL of {size} bytes: expected a binary STL's 84-byte header or 'solid'"
    return (
        f"a binary STL whose header states {declared} triangles ({84 + 50 * declared} bytes) "
        f"but which holds {size} bytes: expected 84 + 50 bytes per triangle"
    )


def _ply_triangles(handle: IO[bytes]) -> int | str:
    head = handle.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return "a PLY file without a header ('ply' ... 'end_header' in its first 64 KB)"
    faces = vertices = 0
    for line in head[:end].splitlines():
        words = line.split()
        if len(words) == 3 and words[0] == b"element" and words[2].isdigit():
            count = int(words[2][:40])
            if words[1] == b"face":
                faces = count
            elif words[1] == b"vertex":
                vertices = count
    return max(faces, vertices // 3)


def mesh_problem(
    handle: IO[bytes], size: int, suffix: str, limits: MeshLimits
) -> tuple[str, str] | None:
    """Why a mesh is refused, as (reason, the ``MeshLimits`` field), or None when it passes.

    Only counts are read: a binary STL's header, the face markers of ASCII STL, OBJ and
    COLLADA text, a PLY header; nothing is parsed into memory.

    Args:
        handle: the mesh, open for reading at its start.
        size: its decoded size [bytes].
        suffix: its file name's suffix (``.stl``...), any case.
        limits: the caps.
    """
    if size > limits.max_bytes:
        return (
            f"a mesh of {size} bytes: expected at most {limits.max_bytes} bytes per mesh",
            "max_bytes",
        )
    kind, limit = suffix.lower(), limits.max_triangles
    found: int | str | None
    exact = kind in (".stl", ".ply")  # counting text stops once past the cap
    if kind == ".stl":
        found = _stl_triangles(handle, size, limit)
    elif kind == ".obj":
        found = _count_tokens(handle, _OBJ_FACE, limit)
    elif kind == ".dae":
        found = _count(handle, _DAE_PRIMITIVE, limit, _dae_count)
    elif kind == ".ply":
        found = _ply_triangles(handle)
    else:
        found = None  # bounded by its size alone
    if isinstance(found, str):
        return found, "max_triangles"
    if found is not None and found > limit:
        shown = found if found < 10**15 else "over 10^15"
        return (
            f"a mesh of {'' if exact else 'at least '}{shown} triangles: expected at most "
            f"{limit} triangles per mesh",
            "max_triangles",
        )
    return None


def check_mesh(path: Path, limits: MeshLimits) -> str | None:
    """Why the mesh file ``path`` must not be loaded (one line), or None when it may be.

    Used before a stored mesh is handed to a mesh loader (the viewer): the same rule as at
    upload, so a mesh stored before the rule, or under larger limits, is never parsed.
    """
    try:
        size = path.stat().st_size
        with open(path, "rb") as handle:
            problem = mesh_problem(handle, size, path.suffix, limits)
    except OSError as exc:
        return f"{path.name}: cannot be read ({exc.strerror or exc})"
    return None if problem is None else f"{path.name}: {problem[0]}"


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


def _open_zip(source: Path | IO[bytes], name: str) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(source)
    except (zipfile.BadZipFile, OSError) as exc:
        raise RobotError(f"{name}: not a readable zip archive ({exc}): expected a .zip") from None


def _check_members(
    archive: zipfile.ZipFile, name: str, limits: MeshLimits | None
) -> list[PurePosixPath]:
    """Every member's name checked, the total unpacked size and (with ``limits``) every mesh
    checked, from the archive alone: nothing is written."""
    members = archive.infolist()
    if len(members) > MAX_FILES:
        raise RobotError(f"{name}: {len(members)} members: expected at most {MAX_FILES} files")
    paths = [_check_member(name, info) for info in members]
    meshes = [
        info
        for info, path in zip(members, paths, strict=True)
        if not info.is_dir() and path.suffix.lower() in MESH_SUFFIXES
    ]
    largest = max(meshes, key=lambda info: info.file_size, default=None)
    if limits is not None and largest is not None and largest.file_size > limits.max_bytes:
        _check_zipped_mesh(archive, largest, name, limits)  # its stated size: nothing read
    total = sum(info.file_size for info in members)
    cap = MAX_BYTES if limits is None else min(limits.max_unpacked, MAX_BYTES)
    if total > cap:
        raise MeshLimitError(
            f"{name}: unpacks to {total} bytes: expected at most {cap} bytes in all",
            "max_unpacked",
        )
    if limits is not None:
        for info in meshes:
            _check_zipped_mesh(archive, info, name, limits)  # faces counted from the text
    return paths


def _check_zipped_mesh(
    archive: zipfile.ZipFile, info: zipfile.ZipInfo, name: str, limits: MeshLimits
) -> None:
    member = one_line(info.filename, 80)
    problem: tuple[str, str] | None
    if info.file_size > limits.max_bytes:  # its declared size: nothing decompressed
        problem = mesh_problem(io.BytesIO(), info.file_size, "", limits)
    else:
        try:
            with archive.open(info) as handle:
                problem = mesh_problem(handle, info.file_size, PurePosixPath(member).suffix, limits)
        except _EXTRACT_ERRORS as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            raise RobotError(
                f"{name}: member '{member}' cannot be read ({reason}): expected a zip of a "
                "robot's folder"
            ) from None
    if problem is not None:
        raise MeshLimitError(f"{name}: member '{member}' is {problem[0]}", problem[1])


def check_package_zip(source: Path | bytes, *, name: str, limits: MeshLimits) -> int:
    """Check a robot package zip against ``limits`` without extracting it.

    Args:
        source: the zip file, or its bytes.
        name: the name messages give it (the user's file name).
        limits: caps on each mesh and on the unpacked total.

    Returns:
        The bytes it unpacks to.

    Raises:
        MeshLimitError: a mesh or the total past a cap, naming the member and the cap.
        RobotError: not a zip, or a member name that is refused (see ``open_robot_package``).
    """
    archive = _open_zip(io.BytesIO(source) if isinstance(source, bytes) else source, name)
    with archive:
        _check_members(archive, name, limits)
        return sum(info.file_size for info in archive.infolist())


def _extract_zip(source: Path, dest: Path, limits: MeshLimits | None = None) -> None:
    archive = _open_zip(source, source.name)
    with archive:
        members = archive.infolist()
        paths = _check_members(archive, source.name, limits)
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


def package_dirs(root: Path) -> tuple[Path, ...]:
    """Folders ``package://name/...`` mesh paths of a robot folder resolve against: the
    folder itself and the parent of every ROS package (``package.xml``) inside it."""
    found = [root]
    for marker in sorted(root.rglob("package.xml")):
        found.append(marker.parent.parent)
    return tuple(dict.fromkeys(found))


def open_robot_package(
    source: str | Path, dest: str | Path | None = None, *, limits: MeshLimits | None = None
) -> RobotPackage:
    """Open a robot folder, or extract a robot zip into ``dest`` and open that.

    Args:
        source: a folder, or a ``.zip`` file.
        dest: folder to extract a zip into (created; required for a zip). Nothing is written
            anywhere else, and nothing at all when the zip is refused.
        limits: when given, a zip's meshes and unpacked total are checked against these
            before anything is extracted (``MeshLimitError``).

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
        _extract_zip(path, Path(dest), limits)
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
        package_dirs=package_dirs(root),
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


#: Every MJCF attribute MuJoCo opens a file by (its XML reference, MuJoCo 3-4): ``file`` of
#: ``<include>``, ``<model>``, ``<mesh>``, ``<hfield>``, ``<skin>``, ``<texture>`` and
#: ``<flexcomp>`` (checked on every element, so an element that gains one is covered too) and
#: the six faces of a cube or skybox ``<texture>``. ``content_type`` names no file.
MJCF_FILE_ATTRIBUTES = (
    "file",
    "fileback",
    "filedown",
    "filefront",
    "fileleft",
    "fileright",
    "fileup",
)
#: The ``<compiler>`` folders asset paths are joined to.
MJCF_DIR_ATTRIBUTES = ("assetdir", "meshdir", "texturedir")


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


@dataclass
class _MjcfFiles:
    """An uploaded MJCF and the files it includes, parsed, with every folder a relative path
    in them may start from (MuJoCo resolves an include from the including file's folder or the
    main file's, an asset from either joined with any compiler folder): a path is accepted
    only when it stays inside the upload from every one of them."""

    root: Path
    main: Path
    trees: dict[Path, Any]
    dirs: set[str]

    def bases(self, path: Path) -> list[PurePosixPath]:
        here = PurePosixPath(path.parent.relative_to(self.root).as_posix())
        top = PurePosixPath(self.main.parent.relative_to(self.root).as_posix())
        return [here] if here == top else [here, top]

    def includes(self, path: Path, value: str) -> list[Path]:
        """The existing files an ``<include file=value>`` in ``path`` may mean (checked)."""
        out = []
        for base in self.bases(path):
            inside = _inside(base, value)
            if inside is None:
                _refuse(path, "include", "file")
            if (self.root / inside).is_file():
                out.append((self.root / inside).resolve())
        return out


def _read_mjcf_files(mjcf: Path, root: Path) -> _MjcfFiles:
    """Parse ``mjcf`` and every file it includes inside ``root``, checking the includes and
    the compiler folders on the way."""
    import xml.etree.ElementTree as ET

    files = _MjcfFiles(root=root, main=mjcf.resolve(), trees={}, dirs={"."})
    pending = [files.main]
    while pending:
        path = pending.pop()
        if path in files.trees or not path.is_file():
            continue  # a missing include inside the upload: MuJoCo says so itself
        try:
            files.trees[path] = tree = ET.parse(path)
        except ET.ParseError:
            continue  # MuJoCo reports the syntax error with its line
        for compiler in tree.iter("compiler"):
            for attr in MJCF_DIR_ATTRIBUTES:
                value = compiler.get(attr)
                if value is None:
                    continue
                if any(_inside(base, value) is None for base in files.bases(path)):
                    _refuse(path, "compiler", attr)
                files.dirs.add(value)
        for element in tree.iter("include"):
            value = element.get("file")
            if value is not None:
                pending.extend(files.includes(path, value))
    return files


def check_mjcf_files(mjcf: Path, root: Path) -> None:
    """Refuse an uploaded MJCF that names a file outside its upload, or replicates too much.

    MuJoCo opens any path the file names (``<include file="/etc/passwd"/>`` was read, and a
    cube texture's ``fileright`` read a server image into the stored robot). Every attribute
    MuJoCo opens a file by (``MJCF_FILE_ATTRIBUTES``) and the compiler's folders must be
    relative paths that stay inside ``root``. This is decided from the text alone, and the
    message never quotes the path: it is the same whatever the path and whether such a file
    exists or not. Included files inside the upload are checked the same way, and their
    ``<replicate>`` copies count with the file that includes them.

    Raises:
        RobotError: names the file, the element and the attribute.
    """
    files = _read_mjcf_files(mjcf, root.resolve())
    for path, tree in files.trees.items():
        bases = files.bases(path)
        for element in tree.iter():
            if not isinstance(element.tag, str) or element.tag == "include":
                continue  # includes were checked while reading them
            for attr in MJCF_FILE_ATTRIBUTES:
                value = element.get(attr)
                if value is None:
                    continue
                for base in bases:
                    for folder in files.dirs:
                        inside = _inside(base, folder)
                        if inside is None or _inside(inside, value) is None:
                            _refuse(path, element.tag, attr)
    try:
        copies = _copies(files, files.main, {}, set())
    except RecursionError:
        raise RobotError(
            f"{mjcf.name}: its elements are nested too deep to count its <replicate> copies: "
            "expected a robot's tree of bodies (a few dozen levels)"
        ) from None
    if copies > MAX_REPLICATED:
        raise RobotError(
            f"{mjcf.name}: its <replicate> elements make {copies} copies in all (the files it "
            f"includes counted): expected at most {MAX_REPLICATED} (a robot arm needs none; "
            "nested replicates multiply)"
        )


#: Copies all ``<replicate>`` elements of an uploaded MJCF may make together: nested ones
#: multiply, and a 1.8 KB file of them took 7.5 GB and two minutes to compile.
MAX_REPLICATED = 1000


def _copies(files: _MjcfFiles, path: Path, memo: dict[Path, int], active: set[Path]) -> int:
    """Copies the ``<replicate>`` elements of ``path`` and the files it includes make, once
    (an include inside a replicate multiplies them like any element inside it)."""
    if path in memo:
        return memo[path]
    if path in active or path not in files.trees:
        return 0  # an include cycle or a file MuJoCo reports itself

    def included(element: Any) -> int:
        targets = files.includes(path, element.get("file") or "")
        return max((_copies(files, t, memo, active) for t in targets), default=0)

    active.add(path)
    memo[path] = _replicated(files.trees[path].getroot(), 1, included)
    active.discard(path)
    return memo[path]


def _replicated(element: Any, factor: int, included: Callable[[Any], int]) -> int:
    """Copies the ``<replicate>`` elements under ``element`` make, each counted with the
    product of the counts around it (``factor``); an ``<include>`` adds ``factor`` times the
    copies its file makes (``included``). Stops counting once over the limit."""
    total = 0
    for child in element:
        inner = factor
        if child.tag == "replicate":
            try:
                inner = factor * max(int(child.get("count", "1")[:12]), 1)
            except ValueError:
                inner = factor  # MuJoCo reports the bad count itself
            total += inner
        elif child.tag == "include":
            total += factor * included(child)
        if total > MAX_REPLICATED or inner > MAX_REPLICATED:
            return max(total, inner)
        total += _replicated(child, inner, included)
    return total


def _refuse(path: Path, tag: str, attr: str) -> NoReturn:
    raise RobotError(
        f"{path.name}: <{tag} {attr}=...>: a path outside the uploaded robot's files: expected "
        "a relative path inside the upload (a zip holds the included files, meshes and "
        "textures)"
    )
