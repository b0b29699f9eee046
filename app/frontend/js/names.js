// The names every page shares, from the one home the server has for them (app/names.py,
// served as GET /api/meta): metrics with units and formulas, the A/B/C phases with their bounds
// and colours, the planning methods' colours, muscle colours, PSO defaults, job states.
// app.js loads them once before any page renders; pages read `names` synchronously.

import { api } from "./api.js";

/** Filled by `loadNames()` before any page renders. */
export const names = /** @type {import("./types").Meta} */ ({});
/** @type {Promise<import("./types").Meta> | null} */
let loading = null;

/** Fetch the shared names once; resolves with `names`. */
export function loadNames() {
  if (!loading) {
    loading = api("/api/meta").then((meta) => Object.assign(names, meta)).catch((err) => {
      loading = null;
      throw err;
    });
  }
  return loading;
}

/**
 * "#rrggbb" with an alpha, as "rgba(r,g,b,a)".
 * @param {string} hex
 * @param {number} alpha 0..1
 * @returns {string}
 */
export function rgba(hex, alpha) {
  const v = hex.replace("#", "");
  const [r, g, b] = [0, 2, 4].map((i) => parseInt(v.slice(i, i + 2), 16));
  return `rgba(${r},${g},${b},${alpha})`;
}

/**
 * A metric's description ({name, unit, label, formula, per_joint, floor}).
 * @param {string} name
 */
export function metric(name) {
  return names.metrics.find((m) => m.name === name);
}

/**
 * The job states after which a job never changes.
 * @param {string} state
 * @returns {boolean}
 */
export function isTerminal(state) {
  return names.terminal_job_states.includes(state);
}
