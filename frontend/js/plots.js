// Plotly, loaded on first use from the installed Python package (served by the API, no CDN).

let loading = null;

export function plotly() {
  if (window.Plotly) return Promise.resolve(window.Plotly);
  if (!loading) {
    loading = new Promise((resolve, reject) => {
      const s = document.createElement("script");
      s.src = "/api/viewer/assets/plotly.min.js";
      s.onload = () => resolve(window.Plotly);
      s.onerror = () => {
        loading = null;
        reject(new Error("Plotly.js could not be loaded from the server"));
      };
      document.head.append(s);
    });
  }
  return loading;
}

export const COLORS = { standard: "#2563eb", optimized: "#ea8c14" };
export const NAMES = { standard: "standard quintic", optimized: "bio-inspired" };
export const PHASE_FILL = {
  A: "rgba(46,160,67,0.10)",
  B: "rgba(212,160,23,0.14)",
  C: "rgba(207,34,46,0.08)",
};

export const CONFIG = {
  responsive: true,
  displaylogo: false,
  modeBarButtonsToRemove: ["select2d", "lasso2d", "autoScale2d"],
};

/** Base layout: compact margins, white template, legend on top. */
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
 */
export function phaseShapes(times, t0, t1, xref = "x", { dashed = null } = {}) {
  const shapes = [];
  if (times && times[0] !== null && times[1] !== null) {
    const edges = [t0, times[0], times[1], t1];
    ["A", "B", "C"].forEach((p, i) => {
      if (edges[i + 1] > edges[i]) {
        shapes.push({
          type: "rect", xref, yref: "paper", x0: edges[i], x1: edges[i + 1], y0: 0, y1: 1,
          fillcolor: PHASE_FILL[p], line: { width: 0 }, layer: "below",
        });
      }
    });
  }
  if (dashed && dashed[0] !== null) {
    for (const t of dashed) {
      if (t === null) continue;
      shapes.push({
        type: "line", xref, yref: "paper", x0: t, x1: t, y0: 0, y1: 1,
        line: { color: COLORS.standard, width: 1, dash: "dot" },
      });
    }
  }
  return shapes;
}

export function phaseLabels(times, xref = "x", t0 = 0) {
  if (!times || times[0] === null || times[1] === null) return [];
  return [
    { x: t0, text: "A", xref, yref: "paper", y: 1, showarrow: false, xanchor: "left", yanchor: "top", font: { size: 11, color: "#6b7280" } },
    { x: times[0], text: "B", xref, yref: "paper", y: 1, showarrow: false, xanchor: "left", yanchor: "top", font: { size: 11, color: "#6b7280" } },
    { x: times[1], text: "C", xref, yref: "paper", y: 1, showarrow: false, xanchor: "left", yanchor: "top", font: { size: 11, color: "#6b7280" } },
  ];
}

/** Plotly.react into a div, loading Plotly first. */
export async function draw(div, traces, lay, config = {}) {
  const P = await plotly();
  await P.react(div, traces, lay, { ...CONFIG, ...config });
  return P;
}
