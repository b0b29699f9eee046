// Plotly, loaded on first use from the installed Python package (served by the API, no CDN).
// Colours come from the shared names (app/names.py via GET /api/meta), loaded before any page.

import { names, rgba } from "./names.js";
import { h } from "./ui.js";

/** @type {Promise<PlotlyStatic> | null} */
let loading = null;

/** Plotly.js, loading it the first time. @returns {Promise<PlotlyStatic>} */
export function plotly() {
  if (window.Plotly) return Promise.resolve(window.Plotly);
  if (!loading) {
    loading = new Promise((resolve, reject) => {
      const s = document.createElement("script");
      s.src = "/api/viewer/assets/plotly.min.js";
      s.onload = () => resolve(/** @type {PlotlyStatic} */ (window.Plotly));
      s.onerror = () => {
        loading = null;
        reject(new Error("Plotly.js could not be loaded from the server"));
      };
      document.head.append(s);
    });
  }
  return loading;
}

/** The two trajectories' colours: the standard quintic's and the paper's method's. */
export function colours() {
  /** @param {string} m a method the server always names */
  const of = (m) => /** @type {{ colour: string }} */ (names.methods.find((x) => x.name === m)).colour;
  return { standard: of("quintic"), optimized: of("paper") };
}
export const NAMES = { standard: "standard quintic", optimized: "bio-inspired" };

/**
 * A translucent fill of a phase's colour, for shading it behind curves.
 * @param {string} phase one of `names.phases` (A, B, C)
 * @param {number} [alpha]
 */
export function phaseFill(phase, alpha = 0.12) {
  return rgba(/** @type {{ colour: string }} */ (names.phases.find((p) => p.name === phase)).colour, alpha);
}

/** Legend entries "■ A high-load capacity" ... for the phases, in their colours. */
export function phaseLegend(withLabels = true) {
  return names.phases.map((p) => h("span", {},
    h("span", { class: "swatch", style: `background:${phaseFill(p.name, 0.4)}` }),
    withLabels ? `${p.name} ${p.label}` : p.name));
}

export const CONFIG = {
  responsive: true,
  displaylogo: false,
  modeBarButtonsToRemove: ["select2d", "lasso2d", "autoScale2d"],
};

/**
 * Base layout: compact margins, white template, legend on top.
 * @param {Record<string, any>} [extra] layout keys that replace the base's
 * @returns {Record<string, any>} a Plotly layout
 */
export function layout(extra = {}) {
  return {
    margin: { l: 56, r: 12, t: 30, b: 40 },
    font: { family: "system-ui, sans-serif", size: 12, color: "#1b1f24" },
    paper_bgcolor: "#fff",
    plot_bgcolor: "#fff",
    hovermode: "x unified",
    legend: { orientation: "h", y: 1.12, x: 0 },
    xaxis: { gridcolor: "#eceff3", zeroline: false },
    yaxis: { gridcolor: "#eceff3", zerolinecolor: "#c9ced6" },
    ...extra,
  };
}

/**
 * Shapes shading the A/B/C phases between boundary times [t_AB, t_BC] on [t0, t1],
 * for one x axis ("x", "x2", ...) across the whole paper height.
 * @param {(number | null)[] | null | undefined} times the phase boundary times [s]
 * @param {number} t0
 * @param {number} t1
 * @param {string} [xref]
 * @param {{ dashed?: (number | null)[] | null }} [options] times [s] drawn as dotted lines
 * @returns {object[]}
 */
export function phaseShapes(times, t0, t1, xref = "x", { dashed = null } = {}) {
  const shapes = [];
  if (times && times[0] !== null && times[1] !== null) {
    const edges = [t0, times[0], times[1], t1];
    names.phases.map((p) => p.name).forEach((p, i) => {
      if (edges[i + 1] > edges[i]) {
        shapes.push({
          type: "rect", xref, yref: "paper", x0: edges[i], x1: edges[i + 1], y0: 0, y1: 1,
          fillcolor: phaseFill(p), line: { width: 0 }, layer: "below",
        });
      }
    });
  }
  if (dashed && dashed[0] !== null) {
    for (const t of dashed) {
      if (t === null) continue;
      shapes.push({
        type: "line", xref, yref: "paper", x0: t, x1: t, y0: 0, y1: 1,
        line: { color: colours().standard, width: 1, dash: "dot" },
      });
    }
  }
  return shapes;
}

/**
 * The phase letters A, B, C over a plot at its start and the two phase times.
 * @param {(number | null)[] | null | undefined} times the two phase boundaries [s]
 * @param {string} [xref] the x axis the letters sit on
 * @param {number} [t0] where phase A starts [s]
 * @returns {object[]} Plotly annotations
 */
export function phaseLabels(times, xref = "x", t0 = 0) {
  if (!times || times[0] === null || times[1] === null) return [];
  return [
    { x: t0, text: "A", xref, yref: "paper", y: 1, showarrow: false, xanchor: "left", yanchor: "top", font: { size: 11, color: "#6b7280" } },
    { x: times[0], text: "B", xref, yref: "paper", y: 1, showarrow: false, xanchor: "left", yanchor: "top", font: { size: 11, color: "#6b7280" } },
    { x: times[1], text: "C", xref, yref: "paper", y: 1, showarrow: false, xanchor: "left", yanchor: "top", font: { size: 11, color: "#6b7280" } },
  ];
}

/** Below this plot width [px] a legend goes under the plot: over it, it hides the curves. */
const NARROW_PLOT = 560;

/**
 * The layout for a narrow plot: a legend of several entries under the plot, not over it.
 * @param {HTMLElement} div
 * @param {any[]} traces Plotly traces
 * @param {any} lay Plotly layout
 * @returns {any}
 */
function fitNarrow(div, traces, lay) {
  const entries = traces.filter((t) => t.name && t.showlegend !== false).length;
  const width = div.clientWidth; // 0 while not laid out: then nothing is known, nothing changes
  if (!width || width >= NARROW_PLOT || lay.showlegend === false || entries < 2) return lay;
  const room = 22 * Math.ceil(entries / 2) + 34;
  const margin = { l: 56, r: 12, t: 30, b: 40, ...lay.margin };
  const height = (lay.height || 300) + room;
  const top = Math.min(margin.t, 24);
  // Under the tick labels and the axis title (about 60 px below the plot area).
  const plotHeight = height - top - (margin.b + room);
  return {
    ...lay,
    height,
    margin: { ...margin, t: top, b: margin.b + room },
    legend: { ...lay.legend, orientation: "h", x: 0, y: -62 / plotHeight, yanchor: "top" },
  };
}

/**
 * Plotly.react into a div, loading Plotly first.
 * @param {HTMLElement} div
 * @param {any[]} traces
 * @param {Record<string, any>} lay a layout (`layout()`)
 * @param {object} [config] Plotly config keys over CONFIG's
 * @returns {Promise<PlotlyStatic>}
 */
export async function draw(div, traces, lay, config = {}) {
  const P = await plotly();
  await P.react(div, traces, fitNarrow(div, traces, lay), { ...CONFIG, ...config });
  return P;
}
