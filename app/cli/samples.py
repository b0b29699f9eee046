"""``bioplan samples``: the permissively licensed sample recordings the README's examples use.

Each file is pinned by its SHA-256 and size: it is downloaded from its public source (the
repository and commit its licence was read from), or copied from a folder that holds it
(``--from DIR``, laid out as the cache is), and checked before it is kept; a file that does not
match is refused and nothing half-written stays. Files already in the cache with the right
checksum are not fetched again. Only sources whose licence is permissive (BSD, MIT, Apache,
CC0) are listed; the GPL-3.0 BTS C3D file the tests also use is not.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import sys
import tempfile
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.cli._common import CliError, add_json_args, emit

#: Environment variable naming a folder to copy the samples from instead of downloading them.
SAMPLES_FROM_ENV = "BIOPLAN_SAMPLES_FROM"


@dataclass(frozen=True)
class Source:
    """Where a group of samples comes from and under which licence."""

    repo: str
    commit: str
    license: str


#: The sources, by key: a public repository at a fixed commit, and its licence.
SOURCES: dict[str, Source] = {
    "biosppy": Source(
        "PIA-Group/BioSPPy", "77550221f77e024459840ece540b1e017ed99e57", "BSD-3-Clause"
    ),
    "bids_bsd": Source(
        "bids-standard/bids-examples", "ca54a02e55548090fced87f38a28bae13a1f692d", "BSD-3-Clause"
    ),
    "bids_cc0": Source(
        "bids-standard/bids-examples", "ca54a02e55548090fced87f38a28bae13a1f692d", "CC0-1.0"
    ),
    "exercise_correction": Source(
        "NgoQuocBao1010/Exercise-Correction", "202a0a802d8d2e3ea42f00e6a8c47da9cafc09d7", "MIT"
    ),
    "collegium_medicum": Source(
        "informacja/Collegium-Medicum", "883e9f407f23729ca0bd82f9e4013478558a4205", "CC0-1.0"
    ),
    "collegium_medicum_2023": Source(
        "informacja/Collegium-Medicum", "317559adf28829ac61a52dd98cc89acb9a54d923", "CC0-1.0"
    ),
    "pyomeca": Source("pyomeca/pyomeca", "3594512b142e4fa029902cc0ea3e74e4f1ef783e", "Apache-2.0"),
    "sports2d": Source(
        "davidpagnon/Sports2D", "9c8a3d2572e57ac0d95d8ebc3efe62d3dc99ddc4", "BSD-3-Clause"
    ),
}


@dataclass(frozen=True)
class Sample:
    """One sample file.

    Attributes:
        path: where it goes in the cache (and where ``--from`` looks), POSIX-style.
        sha256: its checksum (hex).
        size: its size [bytes].
        source: key of :data:`SOURCES`.
        remote: its path in the source repository (renamed to ASCII here).
    """

    path: str
    sha256: str
    size: int
    source: str
    remote: str

    @property
    def url(self) -> str:
        src = SOURCES[self.source]
        return f"https://raw.githubusercontent.com/{src.repo}/{src.commit}/" + urllib.parse.quote(
            self.remote
        )

    @property
    def license(self) -> str:
        return SOURCES[self.source].license


#: Every sample, pinned.
SAMPLES: tuple[Sample, ...] = (
    Sample(
        "biosppy_emg_examples/emg.txt",
        "e9a278c359b2e636049634e2c3ba25d187db828755cc2eeb62a9e89c40235fb5",
        700085,
        "biosppy",
        "examples/emg.txt",
    ),
    Sample(
        "biosppy_emg_examples/emg_1.txt",
        "c3c41791523a0a8f32ee66e82a852a041e45d07d696c0f0e7313518cc23ab7a5",
        319485,
        "biosppy",
        "examples/emg_1.txt",
    ),
    Sample(
        "edf_emg_bids_examples/emg_CustomBipolar/dataset_description.json",
        "730c78b469ebbdc9098f94694d49faaa64ff6735d35ccdfdf983f70f4ae61ba5",
        774,
        "bids_bsd",
        "emg_CustomBipolar/dataset_description.json",
    ),
    Sample(
        "edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight_channels.tsv",
        "7c6e6eb32ad007a407480a07a54fec50cab2ea6d5d5f559b6c8853bc68526c1d",
        95,
        "bids_bsd",
        "emg_CustomBipolar/sub-01/emg/sub-01_task-holdWeight_channels.tsv",
    ),
    Sample(
        "edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight_emg.edf",
        "5150535cf098c430c04b0cca5f4f20cf63fed60fabc81dcfc2a38c2d9fdbb655",
        4512,
        "bids_bsd",
        "emg_CustomBipolar/sub-01/emg/sub-01_task-holdWeight_emg.edf",
    ),
    Sample(
        "edf_emg_bids_examples/emg_CustomBipolar/sub-01_task-holdWeight_emg.json",
        "7c3e0916878a6778be0fe38cc6f196c6526135e8b332bca2fb29fc6c4819715c",
        633,
        "bids_bsd",
        "emg_CustomBipolar/sub-01/emg/sub-01_task-holdWeight_emg.json",
    ),
    Sample(
        "edf_emg_bids_examples/emg_Multimodal/dataset_description.json",
        "baf3f76c2644d6d44a359cbc0af532dc8eaf8dc6981d986d5e001a8b4ad52937",
        859,
        "bids_cc0",
        "emg_Multimodal/dataset_description.json",
    ),
    Sample(
        "edf_emg_bids_examples/emg_Multimodal/sub-01_task-pullstand_channels.tsv",
        "99a0850f9aa944dc02772fa560d02ee5e4a30442977055b9bcb09193ca220ed0",
        531,
        "bids_cc0",
        "emg_Multimodal/sub-01/emg/sub-01_task-pullstand_channels.tsv",
    ),
    Sample(
        "edf_emg_bids_examples/emg_Multimodal/sub-01_task-pullstand_emg.edf",
        "3082fa83a57483882fa0e0cf0ba5f5e743edd5be42352116a0c5e55489293b2f",
        7935,
        "bids_cc0",
        "emg_Multimodal/sub-01/emg/sub-01_task-pullstand_emg.edf",
    ),
    Sample(
        "edf_emg_bids_examples/emg_Multimodal/sub-01_task-pullstand_emg.json",
        "07cd7a1dbe610448486c6edb5e57d195f096761f03470d7cec7f96a4f6e0a155",
        815,
        "bids_cc0",
        "emg_Multimodal/sub-01/emg/sub-01_task-pullstand_emg.json",
    ),
    Sample(
        "mediapipe_bicep_curl_frames/test.csv",
        "81143724e6e6c7a7023746a7ef6a92b4d04983c7ad807fcc956624c7790009ad",
        426018,
        "exercise_correction",
        "core/bicep_model/test.csv",
    ),
    Sample(
        "noraxon_curls_biceps_brachioradialis/NT-01.mat",
        "43251c16078fb87c07d01746ec1ffd5fa733fc8775bb908d6d949a388b079d16",
        594155,
        "collegium_medicum",
        "EMG-Study/Data/Neutral Forearm/NT-01.mat",
    ),
    Sample(
        "noraxon_curls_biceps_brachioradialis/SP-01.mat",
        "c788efeb876037a8520838e9fd4fdc2a90770eb245d116112d2be364aa57541b",
        645532,
        "collegium_medicum",
        "EMG-Study/Data/Supinated Forearm/SP-01.mat",
    ),
    Sample(
        "noraxon_curls_biceps_brachioradialis/2023-04-20-15-07_BR_podchwyt.csv",
        "d9b3394bfb6201eed260eac70a4709053889f735df98f099951c260f7f482efa",
        659252,
        "collegium_medicum_2023",
        "Archiwum/2023-04-20-15-07_BR podchwyt.csv",
    ),
    Sample(
        "noraxon_curls_biceps_brachioradialis/2023-04-20-15-06_BR_posredni.csv",
        "e211bb59a4a63bfe7283d5c35b4836f93c04765698a0dab07e25866d86339ccd",
        895767,
        "collegium_medicum_2023",
        "Archiwum/2023-04-20-15-06_BR pos\u0301redni.csv",
    ),
    Sample(
        "pyomeca_upperlimb_c3d_emg/markers_analogs.c3d",
        "bda1adf05508194dcc543b6eec2bc73991f9208d60bec5e7c6fdb03b7bfd6c15",
        2250816,
        "pyomeca",
        "tests/data/markers_analogs.c3d",
    ),
    Sample(
        "pyomeca_upperlimb_c3d_emg/analogs.csv",
        "7bcfa2410fd69e724a5c194632e7e387ab830576797408647c045254fd8a1392",
        2759785,
        "pyomeca",
        "tests/data/analogs.csv",
    ),
    Sample(
        "pyomeca_upperlimb_c3d_emg/markers.trc",
        "83553145fee43bc86ae618793763c02be7d91e92767d109a6bc2a086a638bb63",
        128340,
        "pyomeca",
        "tests/data/markers.trc",
    ),
    Sample(
        "pyomeca_upperlimb_c3d_emg/inverse_kin.mot",
        "091623c68cdba6242a3cd88491b72d2b286434418738fd830bc91fa987ccf90b",
        26682,
        "pyomeca",
        "tests/data/inverse_kin.mot",
    ),
    Sample(
        "pyomeca_upperlimb_c3d_emg/inverse_dyn.sto",
        "8cacc39160230a66dd7ca7148c55aaa997667aa11bc63fc186a88a7369b3cc00",
        28061,
        "pyomeca",
        "tests/data/inverse_dyn.sto",
    ),
    Sample(
        "video_sports2d_demo/demo.mp4",
        "d9a66417185647b112304b57093f0c180f37a768e6a14daca75ca541f3b78039",
        3968304,
        "sports2d",
        "Sports2D/Demo/demo.mp4",
    ),
)


def default_cache() -> Path:
    """``$XDG_CACHE_HOME/bioplan/samples`` (``~/.cache/bioplan/samples``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "bioplan" / "samples"


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _matches(sample: Sample, path: Path) -> bool:
    return path.is_file() and path.stat().st_size == sample.size and _sha256(path) == sample.sha256


def _download(sample: Sample, target: Path, timeout: float) -> None:
    try:
        with (
            urllib.request.urlopen(sample.url, timeout=timeout) as response,
            target.open("wb") as f,
        ):
            shutil.copyfileobj(response, f)
    except (urllib.error.URLError, OSError) as exc:
        reason = getattr(exc, "reason", None) or exc
        raise CliError(
            f"cannot download {sample.path} from {sample.url} ({reason}): expected network "
            f"access to it, or --from DIR naming a folder that holds the samples"
        ) from None


def fetch(
    sample: Sample, dest: Path, *, source_dir: Path | None = None, timeout: float = 60.0
) -> str:
    """Put ``sample`` into ``dest`` (checked) and say how: "cached", "copied" or "downloaded".

    Raises:
        CliError: it cannot be had, or what was had does not match the pinned checksum.
    """
    target = dest / sample.path
    if _matches(sample, target):
        return "cached"
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=".part-", suffix=target.suffix)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        if source_dir is not None:
            origin = source_dir / sample.path
            if not origin.is_file():
                raise CliError(f"--from {source_dir}: {sample.path} is not there")
            shutil.copyfile(origin, tmp)
            where = str(origin)
        else:
            _download(sample, tmp, timeout)
            where = sample.url
        if not _matches(sample, tmp):
            got = tmp.stat().st_size
            raise CliError(
                f"{sample.path} from {where} does not match its pinned checksum (expected "
                f"{sample.size} bytes with SHA-256 {sample.sha256[:16]}..., got {got} bytes "
                f"with {_sha256(tmp)[:16]}...); nothing was kept"
            )
        tmp.replace(target)
    finally:
        tmp.unlink(missing_ok=True)
    return "copied" if source_dir is not None else "downloaded"


def cmd_samples(args: argparse.Namespace) -> int:
    dest = Path(args.dest) if args.dest else default_cache()
    source = args.source or os.environ.get(SAMPLES_FROM_ENV)
    source_dir = Path(source) if source else None
    if source_dir is not None and not source_dir.is_dir():
        raise CliError(f"--from {source_dir}: no such folder (or ${SAMPLES_FROM_ENV})")
    if args.list:
        lines = [f"{s.path}  {s.size} bytes  {s.license}  {s.url}" for s in SAMPLES]
        emit(args, {"samples": [_describe(s) for s in SAMPLES]}, "\n".join(lines))
        return 0
    done: dict[str, str] = {}
    for sample in SAMPLES:
        done[sample.path] = fetch(sample, dest, source_dir=source_dir)
        if not args.json:
            print(f"{done[sample.path]:>10}  {sample.path} ({sample.license})", file=sys.stderr)
    payload = {"dest": str(dest.resolve()), "files": done}
    emit(args, payload, str(dest))
    return 0


#: What ``--list`` tells of each sample (the attributes of that name, in this order).
LISTED = ("path", "sha256", "size", "license", "url")


def _describe(sample: Sample) -> dict[str, Any]:
    return {name: getattr(sample, name) for name in LISTED}


def register(sub: Any) -> None:
    """Add ``samples`` to the ``bioplan`` subcommands."""
    p = sub.add_parser(
        "samples",
        help="fetch the permissively licensed sample recordings (checksums pinned) into a folder",
    )
    p.add_argument(
        "--dest",
        default=None,
        metavar="DIR",
        help="where to put them (default: $XDG_CACHE_HOME/bioplan/samples, "
        "~/.cache/bioplan/samples); prints the folder",
    )
    p.add_argument(
        "--from",
        dest="source",
        default=None,
        metavar="DIR",
        help="copy them from DIR (laid out as --dest) instead of downloading them, checked the "
        f"same way (default: ${SAMPLES_FROM_ENV} when set, else download)",
    )
    p.add_argument(
        "--list", action="store_true", help="list the files, licences and sources; fetch nothing"
    )
    add_json_args(p, out=False)
    p.set_defaults(handler=cmd_samples)
