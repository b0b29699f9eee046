"""Map muscle labels as vendors write them to the four EMG sites the method uses."""

from __future__ import annotations

import re

from app.errors import BioPlanError
from app.recordings.types import SITES, Site

# Muscles that are not one of the four arm sites. Checked first so that "biceps femoris" is not
# taken for the biceps brachii and "rectus femoris" not for anything at all.
_OTHER_MUSCLES = (
    "femoris",
    "tibialis",
    "gastroc",
    "soleus",
    "vastus",
    "glute",
    "semitend",
    "semimem",
    "hamstring",
    "peroneus",
    "fibularis",
    "adductor",
    "sartorius",
    "gracilis",
    "neck",
    "sternocleido",
    "trapez",
    "trap",
    "pector",
    "pec",
    "latissimus",
    "dorsi",
    "dors",
    "serratus",
    "dent",
    "rhomboid",
    "erector",
    "abdominis",
    "oblique",
    "supraspinatus",
    "supra",
    "infraspinatus",
    "infra",
    "subscap",
    "masseter",
    "brachialis",
)

# (site, token prefixes, exact abbreviations). Prefixes match the start of a token.
_SITE_RULES: tuple[tuple[Site, tuple[str, ...], frozenset[str]], ...] = (
    ("deltoid", ("delt",), frozenset({"dlt"})),
    ("triceps", ("tricep",), frozenset({"tri", "tric", "tb", "trib"})),
    ("biceps", ("bicep",), frozenset({"bic", "bi", "bb", "bicb"})),
    (
        "forearm",
        (
            "brachiorad",
            "forearm",
            "carpi",
            "digitorum",
            "pronator",
            "supinator",
            "ecr",
        ),
        frozenset({"br", "brd", "brr", "ecu", "fcr", "fcu", "edc", "fds", "fdp", "pt", "fa"}),
    ),
)

_GENERIC_MUSCLE_WORDS = ("muscle", "musculus", "brachii", "teres", "flexor", "extensor")


def _tokens(label: str) -> list[str]:
    # Units in brackets are not part of the muscle name ("BRACHIORAD. LT (uV)").
    text = re.sub(r"[\(\[][^\)\]]*[\)\]]", " ", label)
    # camelCase is split so "BicepsBrachi" reads as "biceps brachi".
    text = re.sub(r"([a-z])([A-Z])", r"\1 \2", text)
    return re.sub(r"[^a-z]+", " ", text.lower()).split()


def _other_muscle(tokens: list[str]) -> bool:
    if "pronator" in tokens:  # "pronator teres" is a forearm muscle despite "teres"
        return False
    return any(tok.startswith(word) for tok in tokens for word in _OTHER_MUSCLES) or (
        "teres" in tokens and ("major" in tokens or "minor" in tokens)
    )


def map_muscle(label: str) -> Site | None:
    """The EMG site a muscle label belongs to, or None for other muscles and unknown labels.

    Vendor conventions are understood: Vicon ``"Biceps.EMG4"``, ``"Delt_ant.EMG1"``, Noraxon
    ``"BRACHIORAD. LT (uV)"``, MATLAB field names ``"BicepsBrachi"``, abbreviations (``BIC``,
    ``TRI``, ``DELT``, ``BR``, ``ECRB``, ``FCR``...) and full names. Leg and trunk muscles
    (``"Left Rectus femoris"``, ``"biceps femoris"``) map to None.

    Args:
        label: channel label as written in the file.

    Returns:
        One of ``SITES`` or None.
    """
    tokens = _tokens(label)
    if not tokens or _other_muscle(tokens):
        return None
    for tok in tokens:
        for site, prefixes, exact in _SITE_RULES:
            if tok in exact or any(tok.startswith(p) for p in prefixes):
                return site
    return None


def is_muscle_label(label: str) -> bool:
    """Whether a label names a muscle (any muscle, not only the four sites)."""
    tokens = _tokens(label)
    if not tokens:
        return False
    return (
        map_muscle(label) is not None
        or _other_muscle(tokens)
        or any(tok.startswith(w) for tok in tokens for w in _GENERIC_MUSCLE_WORDS)
    )


def parse_site(value: str, *, what: str) -> Site | None:
    """A site from a user override value (``"none"`` unmaps); raises ValueError when unknown."""
    text = value.strip().lower()
    if text in ("none", ""):
        return None
    for site in SITES:
        if text == site:
            return site
    raise BioPlanError(
        f"{what}: unknown site {value!r} (expected one of {', '.join(SITES)} or 'none')"
    )
