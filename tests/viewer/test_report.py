"""Issue 29 items 3 and 4 on a long slow lift (60 s) planned with every standard method: the
exported report shows what the Compare page shows, and a metric at its floor to round-off is
at the floor, not below it."""

from __future__ import annotations

import html
from html.parser import HTMLParser
from typing import Any

import pytest

from app.viewer.comparison import (
    Comparison,
    comparison_from_arrays,
    floor_state,
    floor_tolerance,
)
from app.viewer.export import report_html

STANDARD = ("quintic", "paper", "human_optimal", "bound", "jerk_limited")


@pytest.fixture(scope="module")
def slow_lift() -> Comparison:
    from app.planning import load_robot, plan

    robot = load_robot("human_arm_2dof")
    result = plan(robot, duration=60.0, methods=STANDARD, particles=8, iterations=5, seed=3)
    return comparison_from_arrays("plan", 11, result.arrays(), result.to_dict(), robot)


class _Tables(HTMLParser):
    """The text of every table cell, by table id, row by row."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self._table: str | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "table":
            self._table = dict(attrs).get("id") or f"table{len(self.tables)}"
            self.tables[self._table] = []
        elif tag == "tr" and self._table is not None:
            self.tables[self._table].append([])
        elif tag in ("td", "th") and self._table is not None:
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None and self._table is not None:
            self.tables[self._table][-1].append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data + " ")


def test_a_metric_at_its_floor_to_round_off_is_at_the_floor(slow_lift: Comparison) -> None:
    """A 60-s lift does about |ΔPE| of absolute work whatever the method; the trapezoidal
    integral may land a hair under the floor, which is round-off, not a below-floor bug."""
    floors = slow_lift.result["floors"]
    tolerance = floor_tolerance("plan")
    states = {
        m: floor_state(v["abs_work"], floors["abs_work"], tolerance)
        for m, v in slow_lift.result["methods"].items()
    }
    values = {m: v["abs_work"] for m, v in slow_lift.result["methods"].items()}
    assert any(v < floors["abs_work"] for v in values.values())  # below it by round-off ...
    assert "below" not in states.values(), (states, values, floors["abs_work"])  # ... not below
    assert "at" in states.values()
    assert floor_state(0.99 * floors["abs_work"], floors["abs_work"], tolerance) == "below"
    assert floor_state(floors["abs_work"] * (1 - 1e-9), floors["abs_work"], 1e-3) == "at"
    assert floor_state(1.01 * floors["abs_work"], floors["abs_work"], tolerance) == "above"


def test_the_report_shows_every_method_like_the_compare_page(slow_lift: Comparison) -> None:
    page = report_html(slow_lift)
    parser = _Tables()
    parser.feed(page)
    metrics = parser.tables["metrics"]
    head = metrics[0]
    labels = {
        "quintic": "standard quintic",
        "paper": "paper's method",
        "human_optimal": "human-like optimum",
        "bound": "physical bound",
        "jerk_limited": "industrial jerk-limited",
    }
    for method in STANDARD:  # every method in the metrics table and the peak-torque table
        assert labels[method] in head, head
        assert any(row and row[0] == labels[method] for row in parser.tables["peak-torque"])
    rows = {row[0].split(" ")[0]: row for row in metrics[1:]}
    result: dict[str, Any] = slow_lift.result
    # Values in method order; changes against the quintic under each; floors or "no floor".
    for metric in ("tau_sq", "abs_work", "pos_work", "peak_power"):
        row = rows[metric]
        for k, method in enumerate(STANDARD):
            assert row[2 + k].startswith(f"{result['methods'][method][metric]:.4g}"), row
        assert "%" in row[3]  # the paper's change
    assert rows["tau_sq"][-1] == "no floor"
    assert rows["abs_work"][-1].startswith(f"{result['floors']['abs_work']:.4g}")
    assert "below floor" not in page  # round-off is not below the floor (item 3)
    assert "at the floor" in page
    share = next(r for r in metrics if r[0].startswith("share of the achievable saving"))
    shares = result["share_of_achievable_pct"]
    for k, method in enumerate(STANDARD):
        value = shares.get(method)
        assert share[2 + k] == ("–" if value is None else f"{value:.1f} %"), share
    # The template's provenance and the recorded human's note, said plainly.
    assert "paper's default" in page and "not from the person's lifts" in page
    assert "no recorded human" in html.unescape(page)
    # No raw Python dicts anywhere in the text (the curves' JSON is in a script: not text).
    text = html.unescape(page.split("<script", 1)[0])
    assert "{'" not in text and "': " not in text
    # The curves draw every method.
    for method in STANDARD:
        assert page.count(f'"name":"{labels[method]}"') == 6 or method == "paper"
