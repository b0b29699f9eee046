"""``read_recording`` / ``read_bytes``: dispatch to a reader, then the checks every format gets."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Literal, TypedDict, Unpack

import numpy as np

from app.recordings._c3d import read_c3d
from app.recordings._common import (
    EMG_MEDIAN_BAND,
    Options,
    Source,
    check_rate,
    emg_median_frequency,
    emg_to_volts,
    is_blank,
    nice_rate,
    split_unit,
    suggest_emg_rate,
)
from app.recordings._csv import read_csv, read_noraxon, read_vicon
from app.recordings._datalog import read_datalog
from app.recordings._edf import read_edf
from app.recordings._mat import read_mat
from app.recordings._mediapipe import read_mediapipe_csv, read_mediapipe_json
from app.recordings._opensim import read_mot, read_sto, read_trc
from app.recordings._sniff import FORMATS, SNIFF_BYTES, SUPPORTED, sniff_bytes
from app.recordings._vendors import read_delsys, read_qualisys
from app.recordings._xdf import read_xdf
from app.recordings.muscles import parse_site
from app.recordings.types import Channel, DatalogSensor, RateCheck, Recording, RecordingError

logger = logging.getLogger("bioplan.recordings")

Reader = Callable[[Source, Options], Recording]

READERS: dict[str, Reader] = {
    "csv": read_csv,
    "noraxon_csv": read_noraxon,
    "vicon_csv": read_vicon,
    "datalog_txt": read_datalog,
    "c3d": read_c3d,
    "edf": read_edf,
    "mat": read_mat,
    "mediapipe_csv": read_mediapipe_csv,
    "mediapipe_json": read_mediapipe_json,
    "trc": read_trc,
    "mot": read_mot,
    "sto": read_sto,
    "delsys_csv": read_delsys,
    "qualisys_tsv": read_qualisys,
    "xdf": read_xdf,
}

_LONGEST_PLAUSIBLE_S = 24 * 3600.0


class ReadKeywords(TypedDict, total=False):
    """The keyword arguments of :func:`read_recording` and :func:`read_bytes` (all default to
    ``None``; described at :func:`read_recording`)."""

    format: str | None
    rate: float | None
    emg_rate: float | None
    muscle_map: Mapping[str, str] | None
    image_size: tuple[int, int] | None
    frame_rate: float | None
    datalog_sensors: Sequence[DatalogSensor] | None
    name: str | None
    sidecars: Mapping[str, bytes] | None


def read_recording(path: str | Path, **options: Unpack[ReadKeywords]) -> Recording:
    """Read any supported recording file into a :class:`Recording` with SI units.

    The format is sniffed from the content unless ``format`` is given. After reading, every
    format gets the same treatment: ``muscle_map`` is applied, ``emg_rate`` replaces the EMG
    rate, channels are checked (at least 2 samples, finite EMG, no constant channel mapped to
    a site), and plausibility warnings go to ``metadata["warnings"]`` (EMG spectral median
    implausible for the rate, with ``metadata["suggested_emg_rate"]``; channel durations
    that disagree).

    Args:
        path: the file.
        format: one of ``FORMATS`` to skip sniffing.
        rate: sampling rate [Hz] for files that state none (headerless CSV, DataLOG without
            sensors, MediaPipe without timestamps). For single-rate files that state one (CSV
            with a time column, Noraxon, MAT, TRC, MOT/STO) it overrides it, with a warning;
            multi-rate files (C3D, EDF, Vicon) ignore it (use ``emg_rate``).
        emg_rate: true rate [Hz] of the EMG channels when the stored one is wrong.
        muscle_map: channel label -> site (``"deltoid"``, ``"triceps"``, ``"biceps"``,
            ``"forearm"``) or ``"none"`` to unmap; overrides the automatic mapping (a site
            given here is taken from the channels mapped to it automatically). Labels match
            exactly, case-insensitively, or without a bracketed unit. Mapping a scalar channel
            of kind "other" makes it EMG (converted to V).
        image_size: (width, height) [px] of the video MediaPipe ran on; undoes the aspect
            distortion of normalised coordinates (x and z times width/height).
        frame_rate: video frame rate [Hz] for landmark files without timestamps.
        datalog_sensors: column definitions for a Biometrics DataLOG export.
        name: the user's file name for messages and ``Recording.source`` (default: the
            path's name).
        sidecars: file name -> bytes of files that belong to this one (BIDS
            ``<stem>_channels.tsv`` and ``<stem>_emg.json`` of an EDF, a DataLOG ``.json``);
            without them, sidecars are looked for beside ``path``.

    Returns:
        The recording; ``metadata["warnings"]`` is always a list of strings.

    Raises:
        RecordingError: the file cannot be read or fails a check; the message names the file,
            the line or channel, and what was expected.
    """
    p = Path(path)
    src = Source(
        name=options.get("name") or p.name, path=p, sidecars=dict(options.get("sidecars") or {})
    )
    if not p.is_file():
        raise src.error("file not found", expected="an existing file")
    return _read(src, options.get("format"), _options(src, options))


def read_bytes(data: bytes, filename: str, **options: Unpack[ReadKeywords]) -> Recording:
    """:func:`read_recording` for bytes already in memory (uploads).

    ``filename`` is the user's file name (used in messages and as an extension hint). Only
    pyedflib needs a real file: EDF bytes go to a temporary file that is removed afterwards.
    Sidecar files (BIDS ``_channels.tsv``/``_emg.json``, DataLOG JSON) uploaded with the file
    come in ``sidecars`` (file name -> bytes).
    """
    src = Source(
        name=options.get("name") or filename,
        content=bytes(data),
        sidecars=dict(options.get("sidecars") or {}),
    )
    return _read(src, options.get("format"), _options(src, options))


def _options(src: Source, options: ReadKeywords) -> Options:
    """The reader options, each checked (rates > 0, image size in pixels, known sites)."""
    unknown = sorted(set(options) - set(ReadKeywords.__annotations__))
    if unknown:
        # A **options signature would otherwise ignore a misspelt keyword silently.
        raise TypeError(f"unexpected keyword argument(s) {unknown}")

    def checked_rate(key: Literal["rate", "emg_rate", "frame_rate"]) -> float | None:
        value = options.get(key)
        return None if value is None else check_rate(value, src=src, what=f"{key} option")

    image_size, muscle_map = options.get("image_size"), options.get("muscle_map")
    opts = Options(
        rate=checked_rate("rate"),
        emg_rate=checked_rate("emg_rate"),
        frame_rate=checked_rate("frame_rate"),
        muscle_map=muscle_map,
        datalog_sensors=options.get("datalog_sensors"),
    )
    if image_size is not None:
        try:
            w, h = (int(v) for v in image_size)
            ok = w > 0 and h > 0 and all(float(v) == int(v) for v in image_size)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise src.error(
                f"image_size {image_size!r}", expected="(width, height) in pixels, both > 0"
            )
        opts.image_size = (w, h)
    if muscle_map is not None:
        for key, value in muscle_map.items():
            try:
                parse_site(str(value), what=f"muscle_map[{key!r}]")
            except ValueError as exc:
                raise src.error(str(exc)) from None
    return opts


def _read(src: Source, format: str | None, opts: Options) -> Recording:
    # Corrupt files can hold 1e308 or inf; every such case is checked explicitly (finite
    # samples, rates), so numpy's floating-point warnings would only be noise.
    with np.errstate(all="ignore"):
        return _read_checked(src, format, opts)


#: Extensions of binary formats: a file so named whose bytes sniff as text was misnamed.
_BINARY_SUFFIXES = {".mat": "mat", ".c3d": "c3d", ".edf": "edf", ".bdf": "edf", ".xdf": "xdf"}


def _misnamed(exc: RecordingError, src: Source, fmt: str) -> RecordingError:
    """A text reader's refusal of a file named like a binary format says so first (a text
    file renamed ``.mat`` got only the CSV parser's complaint)."""
    suffix = Path(src.name).suffix.lower()
    named = _BINARY_SUFFIXES.get(suffix)
    if named is None or named == fmt:
        return exc
    return RecordingError(
        f"is named {suffix} but is not a {named} file; read as {fmt} (what its bytes look "
        f"like): {exc.message}",
        file=exc.file or src.name,
        line=exc.line,
        channel=exc.channel,
        expected=exc.expected,
    )


def _read_checked(src: Source, format: str | None, opts: Options) -> Recording:
    if format is None:
        fmt = sniff_bytes(src.data()[:SNIFF_BYTES], src.name)
    elif format in FORMATS:
        fmt = format
    else:
        raise src.error(f"unknown format {format!r}", expected=f"one of {', '.join(FORMATS)}")
    if fmt not in READERS:
        raise src.error(f"format {fmt!r} has no reader", expected=SUPPORTED)
    if is_blank(src.data()):
        raise src.error("file is empty", expected="a recording")
    try:
        rec = READERS[fmt](src, opts)
    except RecordingError as exc:
        raise _misnamed(exc, src, fmt) if format is None else exc from None
    except MemoryError:
        raise  # out of memory is not a corrupt file (a sandboxed read turns it into a 413)
    except Exception as exc:
        # Third-party parsers raise any exception type on corrupt input; callers are promised
        # RecordingError only, with the file named.
        detail = str(exc)[:200]
        raise src.error(
            f"cannot be read as {fmt}: {type(exc).__name__}: {detail}",
            expected=f"a valid {fmt} file",
        ) from exc
    _apply_muscle_map(rec, src, opts)
    _apply_emg_rate(rec, src, opts)
    _check_channels(rec, src, _user_mapped(rec, opts))
    _check_plausibility(rec, src)
    rec.source = src.name
    warnings = list(rec.metadata.get("warnings", []))
    rec.metadata["warnings"] = warnings + [w for w in src.warnings if w not in warnings]
    if logger.isEnabledFor(logging.INFO):
        kinds: dict[str, int] = {}
        for ch in rec.channels.values():
            kinds[ch.kind] = kinds.get(ch.kind, 0) + 1
        logger.info(
            "%s: read as %s (%s): %s; %d warning(s)",
            src.name, fmt, "sniffed" if format is None else "as asked",
            ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "no channels",
            len(rec.metadata["warnings"]),
        )  # fmt: skip
        for warning in rec.metadata["warnings"]:
            logger.debug("%s: %s", src.name, warning)
    return rec


def _find_channel(rec: Recording, label: str) -> Channel | None:
    if label in rec.channels:
        return rec.channels[label]
    low = label.strip().lower()
    stripped = split_unit(label)[0].strip().lower()
    for ch in rec.channels.values():
        if ch.name.lower() in (low, stripped):
            return ch
    return None


def _apply_muscle_map(rec: Recording, src: Source, opts: Options) -> None:
    if not opts.muscle_map:
        return
    chosen: dict[str, Channel] = {}
    for label, value in opts.muscle_map.items():
        ch = _find_channel(rec, label)
        if ch is None:
            names = list(rec.channels)
            shown = ", ".join(repr(n) for n in names[:20]) + (" ..." if len(names) > 20 else "")
            raise src.error(
                f"muscle_map names channel {label!r}, which is not in the file",
                expected=f"one of {shown}",
            )
        site = parse_site(str(value), what=f"muscle_map[{label!r}]")
        if site is not None and ch.kind != "emg":
            if ch.kind != "other" or ch.data.ndim != 1:
                raise src.error(
                    f"is a {ch.kind} channel and cannot be an EMG site",
                    channel=ch.name,
                    expected="an EMG channel",
                )
            ch.data, ch.unit = emg_to_volts(ch.data, ch.unit or None, src=src, channel=ch.name)
            ch.kind = "emg"
        ch.site = site
        chosen[ch.name] = ch
    # A site the user assigns is taken away from channels mapped to it automatically, so
    # the user's channel is the one used for that site.
    taken = {ch.site for ch in chosen.values() if ch.site is not None}
    for ch in rec.channels.values():
        if ch.name not in chosen and ch.site in taken:
            ch.site = None


def _apply_emg_rate(rec: Recording, src: Source, opts: Options) -> None:
    if opts.emg_rate is None:
        return
    emg = rec.of_kind("emg")
    if not emg:
        src.warn("emg_rate option given but the file has no EMG channel")
        return
    stored = sorted({ch.rate for ch in emg})
    rec.metadata["stored_emg_rate"] = stored[0] if len(stored) == 1 else stored
    for ch in emg:
        ch.rate = opts.emg_rate
        ch.time = None  # the stored times were computed from the wrong rate


def _user_mapped(rec: Recording, opts: Options) -> set[str]:
    """Names of the channels the user's muscle map sends to a site."""
    out: set[str] = set()
    for label, value in (opts.muscle_map or {}).items():
        ch = _find_channel(rec, label)
        if ch is not None and str(value).strip().lower() != "none":
            out.add(ch.name)
    return out


def _check_channels(rec: Recording, src: Source, user_mapped: set[str] | None = None) -> None:
    """Rates, sample counts, finite EMG; constant channels are noted and left unmapped (a
    constant channel the user mapped to a site is an error: that muscle carries no signal)."""
    if not rec.channels:
        raise src.error("has no channels", expected="at least one signal")
    flat: list[Channel] = []
    scalars = 0
    for ch in rec.channels.values():
        check_rate(ch.rate, src=src, what="sampling rate", channel=ch.name)
        if ch.n_samples < 2:
            raise src.error(
                f"has {ch.n_samples} sample(s)", channel=ch.name, expected="at least 2 samples"
            )
        if ch.data.ndim != 1:
            continue
        scalars += 1
        # min/max propagate NaN, so one pass tells both "all finite" and "constant"
        lo, hi = float(np.min(ch.data)), float(np.max(ch.data))
        if not (math.isfinite(lo) and math.isfinite(hi)):
            finite = np.isfinite(ch.data)
            if ch.kind == "emg":
                i = int(np.flatnonzero(~finite)[0])
                raise src.error(
                    f"sample {i} (t = {ch.times[i]:.4g} s) is missing or not finite",
                    channel=ch.name,
                    expected="finite EMG samples",
                )
            if not finite.any():
                continue
            lo, hi = float(np.min(ch.data[finite])), float(np.max(ch.data[finite]))
        if lo == hi:
            if ch.site is not None and ch.name in (user_mapped or set()):
                raise src.error(
                    f"is constant ({lo:g} {ch.unit}) but mapped to the {ch.site} site",
                    channel=ch.name,
                    expected="a signal that varies (is the sensor connected?)",
                )
            if ch.site is not None:
                src.warn(f"channel {ch.name!r} is constant: not used as the {ch.site} site")
                ch.site = None
            flat.append(ch)
    if (
        scalars
        and len(flat) == scalars
        and not rec.of_kind("marker")
        and not rec.of_kind("landmark")
    ):
        raise src.error(
            "is constant (zero variance), as is every channel in the file",
            channel=flat[0].name,
            expected="at least one signal that varies",
        )
    if flat:
        rec.metadata["flat_channels"] = [c.name for c in flat]
        names = ", ".join(repr(c.name) for c in flat[:10]) + (" ..." if len(flat) > 10 else "")
        src.warn(f"{len(flat)} constant channel(s) (zero variance, probably unused): {names}")


def _check_plausibility(rec: Recording, src: Source) -> None:
    lo, hi = EMG_MEDIAN_BAND
    # One verdict per group of EMG channels sharing a rate: a rate is wrong for all of them,
    # while one channel with poor contact or artefacts can have an odd spectrum on its own.
    groups: dict[float, list[tuple[Channel, float]]] = {}
    for ch in rec.of_kind("emg"):
        if ch.data.ndim != 1:
            continue
        median = emg_median_frequency(ch.data, ch.rate)
        if median is not None:
            groups.setdefault(ch.rate, []).append((ch, median))
    for rate, members in groups.items():
        median = float(np.median([m for _, m in members]))
        if lo <= median <= hi:
            continue
        suggested = suggest_emg_rate(median, rate)
        rec.metadata["suggested_emg_rate"] = suggested
        names = ", ".join(repr(ch.name) for ch, _ in members[:6])
        names += " ..." if len(members) > 6 else ""
        reason = (
            f"EMG spectral median {median:.0f} Hz at {rate:g} Hz is implausible (surface EMG is"
            f" typically 50-150 Hz) for {names}; at {suggested:g} Hz it would be"
            f" {median * suggested / rate:.0f} Hz - give emg_rate={suggested:g}"
            f" (--emg-rate {suggested:g}) if that is the true rate"
        )
        rec.metadata["rate_check"] = RateCheck(
            stored_rate=rate,
            suggested_rate=suggested,
            median_frequency=median,
            channels=tuple(ch.name for ch, _ in members),
            reason=reason,
        ).to_dict()
        src.warn(reason)
    _check_durations(rec, src)


def _check_durations(rec: Recording, src: Source) -> None:
    """Warn about channels whose duration disagrees with the rest (a wrong per-channel rate).

    The reference is the duration most channels share (within 2 %); on a tie, the one of an
    EMG channel, whose rate the spectral check vouches for.
    """
    channels = [ch for ch in rec.channels.values() if ch.time is None]
    for ch in channels:
        if ch.duration > _LONGEST_PLAUSIBLE_S:
            src.warn(
                f"channel {ch.name!r} lasts {ch.duration / 3600:.1f} h at {ch.rate:g} Hz;"
                " is the rate right?"
            )
    clusters: list[list[Channel]] = []
    for ch in channels:
        for group in clusters:
            ref = group[0].duration
            if abs(ch.duration - ref) <= 0.02 * ref + 2.0 / ch.rate:
                group.append(ch)
                break
        else:
            clusters.append([ch])
    if len(clusters) < 2:
        return
    best = max(clusters, key=lambda g: (len(g), any(c.kind == "emg" for c in g)))
    ref = best[0].duration
    if ref <= 0:
        return
    for group in clusters:
        if group is best:
            continue
        for ch in group:
            src.warn(
                f"channel {ch.name!r} lasts {ch.duration:.3g} s at {ch.rate:g} Hz while the"
                f" recording lasts {ref:.3g} s; {nice_rate(ch.n_samples / ref):.6g} Hz would match"
            )
