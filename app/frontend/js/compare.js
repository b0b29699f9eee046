// Compare: standard vs optimised. Curves per joint with the phases shaded, the metrics table
// with changes and physical floors, the sweep heat maps, and the 3-D viewer below.

import { api, qs } from "./api.js";
import { names } from "./names.js";
import { NAMES, colours, draw, layout, phaseLabels, phaseLegend, phaseShapes, plotly } from "./plots.js";
import { banner, clear, fmt, h, messageOf, pct, when } from "./ui.js";

const LABELS = ["standard", "optimized"];
// Results name their floors after the physics (ΔPE, ΔPE/T); the shared names after the metric
// each one bounds. A floor the result reports under the metric's own name is taken first.
const FLOOR_KEYS = { abs_work: "delta_potential", pos_work: "delta_potential", peak_power: "min_peak_power" };
const FLOOR_LABELS = { delta_potential: "ΔPE", min_peak_power: "ΔPE/T" };

/** [key, formula, unit, floor key in result.floors or null] of the per-trajectory metrics. */
function metricRows(floors) {
  return names.metrics.filter((m) => !m.per_joint).map((m) => {
    const key = m.floor === null ? null : m.floor in floors ? m.floor : FLOOR_KEYS[m.floor] ?? null;
    return [m.name, m.formula, m.unit, key];
  });
}

function title(item, kind) {
  const c = (item.result && item.result.conditions) || item.job.params || {};
  const payload = c.payload ?? item.job.params.payload;
  return `${kind === "simulation" ? "Simulation" : "Plan"} #${item.id}: ${item.robot}, ${payload ?? "default"} kg, ${c.duration ?? item.job.params.duration} s, ${c.objective ?? item.job.params.objective}`;
}

/** Per-joint power |τ_j ω_j| [W] and its running integral [J] (trapezoid). */
function jointPower(t, tau, qd, j) {
  const p = t.map((_, i) => Math.abs(tau[i][j] * qd[i][j]));
  const e = [0];
  for (let i = 1; i < t.length; i++) e.push(e[i - 1] + 0.5 * (p[i] + p[i - 1]) * (t[i] - t[i - 1]));
  return [p, e];
}

export async function render(main, [kindArg, idArg]) {
  const [plans, sims, sweeps] = await Promise.all([
    api(`/api/plans${qs({ state: "succeeded", limit: 100 })}`),
    api(`/api/simulations${qs({ state: "succeeded", limit: 100 })}`),
    api(`/api/sweeps${qs({ state: "succeeded", limit: 5 })}`).catch(() => ({ items: [] })),
  ]);
  const options = [
    ...sims.items.map((x) => ({ kind: "simulation", item: x })),
    ...plans.items.map((x) => ({ kind: "plan", item: x })),
  ].sort((a, b) => b.item.id - a.item.id);

  const head = h("div", { class: "page-head" }, h("h1", {}, "Compare standard and bio-inspired motion"));
  main.append(head);
  if (!options.length) {
    main.append(banner("info", "No finished plan or simulation yet. "), h("a", { class: "button primary", href: "#/plan" }, "Plan one"));
    if (sweeps.items.length) main.append(sweepCard(sweeps.items[0]));
    return;
  }
  let kind = kindArg;
  let id = Number(idArg);
  if (!kind || !options.some((o) => o.kind === kind && o.item.id === id)) {
    if (kind) main.append(banner("warn", `${kind} #${idArg} is not a finished comparison; showing the newest.`));
    ({ kind } = options[0]);
    id = options[0].item.id;
  }
  const selected = options.find((o) => o.kind === kind && o.item.id === id);
  const picker = h("select", { id: "comparison-select", "aria-label": "Comparison" },
    options.map((o) => h("option", { value: `${o.kind}/${o.item.id}`, selected: o.kind === kind && o.item.id === id }, title(o.item, o.kind))));
  picker.addEventListener("change", () => (location.hash = `#/compare/${picker.value}`));
  head.append(h("div", { class: "actions", style: "min-width:min(100%,520px)" }, picker));

  let data;
  try {
    data = await api(`/api/viewer/comparisons/${kind}/${id}${qs({ points: 400 })}`);
  } catch (err) {
    main.append(banner("error", messageOf(err)));
    return;
  }
  const result = data.result;
  const curves = data.curves;

  // ---- conditions and metrics -------------------------------------------------------
  const cond = result.conditions || {};
  const warnings = result.warnings || [];
  main.append(
    h("section", { class: "card" },
      h("div", { class: "facts" },
        fact("robot", data.robot),
        fact("payload", `${fmt(data.payload.mass)} kg`),
        fact("duration", `${fmt(data.duration)} s`),
        fact("objective", cond.objective || "–"),
        fact("elbow velocity peak", `${fmt(result.optimized.peak_velocity_angle_deg, 3)}° (standard ${fmt(result.standard.peak_velocity_angle_deg, 3)}°)`),
        fact("human template", templateText(selected, result)),
      ),
      warnings.length ? h("details", { class: "small", style: "margin-top:8px" }, h("summary", {}, `${warnings.length} warning(s)`), h("ul", {}, warnings.map((w) => h("li", {}, w)))) : null,
    ),
    metricsCard(kind, result, data.joint_names),
  );

  // ---- curves -----------------------------------------------------------------------
  const jointNames = curves.joint_names;
  let joint = data.elbow_joint;
  const seg = h("div", { class: "seg", role: "group", "aria-label": "Joint" });
  const grid = h("div", { class: "grid-plots", id: "curves" });
  const divs = Object.fromEntries(["qd", "qdd", "tau", "power", "energy"].map((k) => [k, h("div", { class: "plot", id: `plot-${k}` })]));
  Object.values(divs).forEach((d) => grid.append(h("div", {}, d)));
  grid.append(h("div", { class: "plot-note" }, legendBox()));
  jointNames.forEach((name, j) => {
    const b = h("button", { type: "button", class: j === joint ? "on" : "", onclick: () => {
      joint = j;
      seg.querySelectorAll("button").forEach((x, k) => x.classList.toggle("on", k === j));
      drawCurves();
    } }, name);
    seg.append(b);
  });
  main.append(h("section", { class: "card" },
    h("div", { class: "row", style: "margin-bottom:8px" }, h("h2", { style: "margin:0" }, "Curves per joint"), h("div", { style: "margin-left:auto; max-width:100%" }, seg)),
    grid,
  ));

  const t = curves.t;
  const tEnd = t[t.length - 1];
  const phases = data.phase_times;
  async function drawCurves() {
    const j = joint;
    const name = jointNames[j];
    const specs = {
      qd: [`${name} velocity [rad/s]`, (c) => c.qd.map((r) => r[j])],
      qdd: [`${name} acceleration [rad/s²]`, (c) => c.qdd.map((r) => r[j])],
      tau: [`${name} torque [Nm]`, (c) => c.tau.map((r) => r[j])],
      power: [`${name} power |τ·ω| [W]`, (c) => jointPower(t, c.tau, c.qd, j)[0]],
      energy: [`${name} cumulative energy [J]`, (c) => jointPower(t, c.tau, c.qd, j)[1]],
    };
    await Promise.all(Object.entries(specs).map(([k, [label, get]]) => {
      const colour = colours();
      const traces = LABELS.map((l) => ({ x: t, y: get(curves[l]), mode: "lines", name: NAMES[l], line: { color: colour[l], width: 2 } }));
      if (k === "power" || k === "energy") {
        // The robot's total next to the joint's, dotted.
        LABELS.forEach((l) => traces.push({ x: t, y: curves[l][k], mode: "lines", name: `${NAMES[l]}, all joints`, line: { color: colour[l], width: 1.5, dash: "dot" } }));
      }
      return draw(divs[k], traces, layout({
        height: 270,
        title: { text: label, font: { size: 13 }, x: 0.01, xanchor: "left" },
        showlegend: false,
        margin: { l: 56, r: 10, t: 34, b: 36 },
        xaxis: { title: { text: "t [s]" }, gridcolor: "#eceff3", range: [t[0], tEnd] },
        shapes: phaseShapes(phases.optimized, t[0], tEnd, "x", { dashed: phases.standard }),
        annotations: phaseLabels(phases.optimized),
      }));
    }));
  }
  await plotly();
  await drawCurves();

  // ---- sweep ------------------------------------------------------------------------
  const sweep = sweeps.items.find((s) => s.robot === data.robot) || sweeps.items[0];
  if (sweep) main.append(sweepCard(sweep));

  // ---- 3-D viewer -------------------------------------------------------------------
  const viewerCard = h("section", { class: "card", id: "viewer-card" },
    h("div", { class: "row", style: "margin-bottom:8px" },
      h("h2", { style: "margin:0" }, "3-D viewer"),
      h("span", { class: "small muted" }, "blue: standard · amber: bio-inspired · play, pause, speed, scrub and layout in the viewer's panel"),
      h("span", { class: "actions row", style: "margin-left:auto" },
        h("a", { class: "button small", id: "export-scene", href: data.exports.scene, download: "" }, "Export 3-D scene (HTML)"),
        h("a", { class: "button small", id: "export-report", href: data.exports.report, download: "" }, "Export report (HTML)"),
      ),
    ),
  );
  if (data.viewer.enabled) {
    // The viewer listens on its own port; on a wildcard bind use the host the page came from.
    const host = ["0.0.0.0", "::", ""].includes(data.viewer.host) ? location.hostname : data.viewer.host;
    const url = data.viewer.url.replaceAll(`${data.viewer.host}:`, `${host}:`);
    viewerCard.append(
      h("iframe", { class: "viewer-frame", id: "viewer-frame", src: url, title: "3-D comparison viewer", allow: "fullscreen" }),
      h("p", { class: "small muted" }, "Each tab gets its own scene. ", h("a", { href: url, target: "_blank", rel: "noopener" }, "Open the viewer alone ↗")),
    );
  } else {
    viewerCard.append(banner("info", "The 3-D viewer is not running on this server; the exports still work."));
  }
  main.append(viewerCard);
}

function templateText(option, result) {
  const params = option ? option.item.job.params : {};
  const target = result.target_peak_velocity_angle_deg ?? (result.conditions || {}).target_peak_velocity_angle_deg;
  const source = params.template_analysis_id ? `analysis #${params.template_analysis_id}` : params.template ? "uploaded" : (result.conditions || {}).template || "paper defaults";
  return target === undefined ? source : `${source}, target ${fmt(target, 3)}°`;
}

function fact(k, v) {
  return h("div", { class: "fact" }, h("div", { class: "k" }, k), h("div", { class: "v", style: "font-size:14px" }, v));
}

function legendBox() {
  return h("div", { class: "legend-inline" },
    h("span", {}, h("span", { class: "swatch sw-std" }), "standard quintic"),
    h("span", {}, h("span", { class: "swatch sw-opt" }), "bio-inspired (PSO)"),
    h("span", {}, "dotted: all joints (power, energy)"),
    phaseLegend(false),
    h("span", {}, "(phases of the optimised motion; blue dots: the standard's)"),
  );
}

function metricsCard(kind, result, jointNames) {
  const floors = result.floors || {};
  const imp = result.improvement_pct || {};
  const planned = result.planned ? result.planned.improvement_pct || {} : null;
  const rows = metricRows(floors).map(([key, def, unit, floorKey]) => {
    const s = result.standard[key];
    const o = result.optimized[key];
    const floor = floorKey ? floors[floorKey] : null;
    const below = floor !== null && floor !== undefined && (s < floor - 1e-9 * Math.abs(floor) || o < floor - 1e-9 * Math.abs(floor));
    const change = imp[key];
    return h("tr", { dataset: { metric: key } },
      h("td", {}, h("strong", {}, key), h("div", { class: "small muted" }, def)),
      h("td", {}, unit),
      h("td", { class: "num" }, fmt(s)),
      h("td", { class: "num" }, fmt(o)),
      h("td", { class: `num ${change > 0.05 ? "better" : change < -0.05 ? "worse" : ""}` }, pct(change)),
      planned ? h("td", { class: "num small" }, pct(planned[key])) : null,
      h("td", { class: "num" }, floor === null || floor === undefined ? h("span", { class: "muted" }, "–") : `${fmt(floor)} (${FLOOR_LABELS[floorKey] ?? floorKey})`),
      h("td", {}, floor === null || floor === undefined ? "" : below ? h("span", { class: "worse" }, "below floor!") : h("span", { class: "small muted" }, "≥ floor")),
    );
  });
  const joints = jointNames || result.standard.peak_torque.map((_, i) => `J${i + 1}`);
  const torque = h("table", { id: "torque-table" },
    h("thead", {}, h("tr", {}, h("th", {}, "peak torque [Nm]"), joints.map((j) => h("th", { class: "num mono" }, j)))),
    h("tbody", {}, LABELS.map((l) => h("tr", {}, h("td", {}, NAMES[l]), result[l].peak_torque.map((v) => h("td", { class: "num" }, fmt(v)))))),
  );
  return h("section", { class: "card" },
    h("h2", {}, kind === "simulation" ? "Metrics measured in the MuJoCo simulation" : "Metrics of the planned trajectories"),
    h("div", { class: "table-wrap" },
      h("table", { id: "metrics-table" },
        h("thead", {}, h("tr", {},
          h("th", {}, "metric"), h("th", {}, "unit"), h("th", { class: "num" }, "standard"), h("th", { class: "num" }, "optimised"),
          h("th", { class: "num" }, "change"), planned ? h("th", { class: "num" }, "planned change") : null,
          h("th", { class: "num" }, "physical floor"), h("th", {}, ""))),
        h("tbody", {}, rows),
      ),
    ),
    h("p", { class: "small muted" }, "Change = 100 (standard − optimised) / standard: positive (green) means the bio-inspired plan uses less. Floors: no rest-to-rest motion does less positive work than ΔPE, and none has a lower peak power than ΔPE/T."),
    h("div", { class: "table-wrap", style: "margin-top:10px" }, torque),
  );
}

function sweepCard(sweep) {
  const r = sweep.result;
  const objectives = r.objectives;
  const metrics = r.metrics;
  let objective = objectives[0];
  let metric = metrics.includes("abs_work") ? "abs_work" : metrics[0];
  const div = h("div", { class: "plot", id: "sweep-plot", style: "min-height:360px" });
  const selObj = h("select", { "aria-label": "Sweep objective" }, objectives.map((o) => h("option", { value: o }, `objective ${o}`)));
  const selMet = h("select", { "aria-label": "Sweep metric" }, metrics.map((m) => h("option", { value: m, selected: m === metric }, `metric ${m}`)));
  const redraw = () => {
    const table = r.tables[objective][metric];
    const z = table.change_pct;
    const text = z.map((row, i) => row.map((v, k) => `${v === null ? "–" : `${v > 0 ? "+" : ""}${v.toFixed(1)} %`}<br>${table.classification[i][k]}`));
    const lim = Math.max(5, ...z.flat().filter((v) => v !== null).map((v) => Math.abs(v)));
    draw(div, [{
      type: "heatmap", z, x: r.payloads.map((p) => `${p} kg`), y: r.durations.map((d) => `${d} s`), text, texttemplate: "%{text}",
      hovertemplate: "T %{y}, m %{x}: %{z:.1f} %<extra></extra>", zmin: -lim, zmax: lim, zmid: 0,
      colorscale: [[0, "#cf222e"], [0.5, "#f6f8fa"], [1, "#1a7f37"]], colorbar: { title: { text: "change [%]" } },
    }], layout({ height: 360, hovermode: "closest", xaxis: { title: { text: "payload" } }, yaxis: { title: { text: "duration" } }, margin: { l: 70, r: 10, t: 20, b: 50 } }));
  };
  selObj.addEventListener("change", () => { objective = selObj.value; redraw(); });
  selMet.addEventListener("change", () => { metric = selMet.value; redraw(); });
  const card = h("section", { class: "card", id: "sweep-card" },
    h("div", { class: "row" }, h("h2", { style: "margin:0" }, `Sweep #${sweep.id}: ${r.robot}`), h("span", { class: "small muted" }, when(sweep.job.finished_at)),
      h("span", { class: "row", style: "margin-left:auto" }, selObj, selMet)),
    h("p", { class: "small muted" }, "Where the bio-inspired plan wins (green) and where it does not (red): change in % of the standard, per duration and payload."),
    div,
  );
  plotly().then(redraw);
  return card;
}
