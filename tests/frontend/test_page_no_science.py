"""The dashboard draws and never computes: no numeric integration, no power products of torque
and velocity, no formulas and no hard-coded lists of metrics in ``app/frontend/js``. Those come
from the API (per-joint power and energy with the comparison's curves; the floors' formulas, the
front's axes and their words from ``/api/meta``). Each rule is shown to catch the code it
replaced (the planted snippets are what the pages held before)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from app.names import FRONT_AXES, METRICS

JS = Path(__file__).resolve().parents[2] / "app" / "frontend" / "js"

#: Every metric and front-axis name: two or more of them in one array literal is a metric list.
METRIC_NAMES = frozenset(METRICS) | frozenset(FRONT_AXES)

RULES: dict[str, re.Pattern[str]] = {
    # x[i] - x[i - 1]: a step between consecutive samples (trapezoid or rectangle sums).
    "numeric integration": re.compile(r"(\w+)\[\s*(\w+)\s*\]\s*-\s*\1\[\s*\2\s*-\s*1\s*\]"),
    # tau[...] * qd[...] (either order): mechanical power computed in the page.
    "power product": re.compile(
        r"\btau\w*(?:\[[^\]]*\])+\s*\*\s*qd\w*\[|\bqd\w*(?:\[[^\]]*\])+\s*\*\s*tau\w*\["
    ),
    # The floors' formulas and their physics' names belong to the server.
    "floor formula": re.compile(r"ΔPE|delta_potential|min_peak_power"),
    # An integral written out (a front's jerk ∫Σ q⃛² dt): the server names its measures.
    "formula": re.compile(r"∫"),
}


def _code(text: str) -> str:
    """``text`` without block comments and whole-line comments (what runs)."""
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("//"))


def science_in(text: str) -> list[str]:
    """What in ``text`` (JavaScript) computes or writes science the API should send."""
    code = _code(text)
    found = [f"{rule}: {m.group(0)!r}" for rule, rx in RULES.items() for m in rx.finditer(code)]
    for literal in re.finditer(r"\[([^\[\]]*)\]", code):
        quoted = set(re.findall(r"""["'`](\w+)["'`]""", literal.group(1)))
        if len(quoted & METRIC_NAMES) >= 2:
            found.append(f"hard-coded metric list: {literal.group(0)[:80]!r}")
    return found


@pytest.mark.parametrize("name", sorted(p.name for p in JS.glob("*.js")))
def test_the_page_computes_no_science(name: str) -> None:
    assert science_in((JS / name).read_text(encoding="utf-8")) == []


#: The code each rule replaced (compare.js, front.js and plan.js before the API sent it).
PLANTS = {
    "numeric integration": """
function jointPower(t, tau, qd, j) {
  const p = t.map((_, i) => Math.abs(tau[i][j] * qd[i][j]));
  const e = [0];
  for (let i = 1; i < t.length; i++) e.push(e[i - 1] + 0.5 * (p[i] + p[i - 1]) * (t[i] - t[i - 1]));
  return [p, e];
}""",
    "power product": "const p = t.map((_, i) => Math.abs(tau[i][j] * qd[i][j]));",
    "floor formula": """const FLOOR_TEXT = { abs_work: "|ΔPE|", pos_work: "max(ΔPE, 0)" };
const LEGACY_FLOOR_KEYS = { abs_work: "delta_potential", peak_power: "min_peak_power" };""",
    "formula": """const AXIS_TEXT = {
  jerk: { label: "jerk ∫Σ q⃛² dt (smoothness)", unit: "rad²/s⁵" },
};""",
    "hard-coded metric list": """
const FRONT_AXES = ["tau_sq", "abs_work", "pos_work", "electrical_energy", "peak_power",
  "peak_torque", "jerk", "duration"];
...["abs_work", "pos_work", "electrical_energy", "peak_power"].map((k) => k);""",
}


@pytest.mark.parametrize("rule", sorted(PLANTS))
def test_the_check_finds_the_science_it_replaced(rule: str) -> None:
    found = science_in(PLANTS[rule])
    assert any(f.startswith(f"{rule}:") for f in found), found


def test_comments_may_name_what_the_server_computes() -> None:
    text = "// power |τ·ω| and ΔPE come from the API\n/* x[i] - x[i - 1] */\nconst a = 1;\n"
    assert science_in(text) == []
