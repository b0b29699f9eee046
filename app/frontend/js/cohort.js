// Cohort: pick stored recordings (grouped by their condition, or into named groups), the
// comparison's options (from GET /api/cohorts/options: the library's CohortOptions), submit the
// job and follow it; then the result as the server computed it: per group n, mean ± SD and
// median [IQR] per measure, the tests with their p-values (raw and corrected, naming the
// correction) and effect sizes, strip/box plots per measure, the onset order per group, the CSV.
// The page draws; it never computes a statistic.

import { api, followJob, qs } from "./api.js";
import { draw, layout } from "./plots.js";
import { banner, clear, fmt, h, inFormWords, tag, when } from "./ui.js";

/** Group colours, in group order (any two groups differ). */
const PALETTE = ["#2563eb", "#ea8c14", "#16a34a", "#9333ea", "#dc2626", "#0891b2", "#a16207", "#db2777"];
/** @type {Record<string, string>} */
const FIELD_WORDS = { groups: "Groups", group_by: "Grouping", recording_ids: "Recordings", options: "Options" };
/** @type {Record<string, string>} */
const TEST_WORDS = { welch_t: "Welch's t", mann_whitney_u: "Mann-Whitney U", paired_t: "paired t", wilcoxon: "Wilcoxon signed-rank" };
/** @type {Record<string, string>} */
const EFFECT_WORDS = { hedges_g: "Hedges' g", hedges_g_z: "Hedges' g_z", rank_biserial: "rank-biserial r" };

/**
 * An option of the comparison (GET /api/cohorts/options: the library's CohortOptions).
 * @typedef {{ name: string, type: string, default: any, choices?: string[] | null, minimum: number | null,
 *   unit?: string | null, help: string }} CohortOption
 */
/**
 * The comparison's statistics (app/analysis/cohort.py `CohortResult.to_dict`), typed by the
 * server's model (app/api/result_models.py `CohortResult`).
 * @typedef {import("./api_types").CohortResult} CohortResult
 */
/** @typedef {import("./api_types").CohortResultOut} CohortResultOut */

/**
 * @param {HTMLElement} main
 * @param {Array<string | undefined>} match the comparison's id, if any
 */
export async function render(main, [id]) {
  /** @type {(() => void)[]} */
  const stops = [];
  if (id) await resultPage(main, Number(id), stops);
  else await formPage(main, stops);
  return () => stops.forEach((s) => s());
}

// ---- the form ----------------------------------------------------------------------------

/** @param {CohortOption} o */
function optionInput(o) {
  const attrs = { id: `opt-${o.name}`, name: o.name, title: o.help };
  if (o.choices) return h("select", attrs, o.choices.map((c) => h("option", { value: c, selected: c === o.default }, c)));
  if (o.type === "string") return h("input", { ...attrs, value: o.default ?? "", maxlength: "200" });
  const input = h("input", { ...attrs, type: "number", step: o.type === "integer" ? "1" : "any", placeholder: o.default === null ? "none" : "" });
  if (o.default !== null) input.value = String(o.default);
  if (o.minimum !== null) input.min = String(o.minimum);
  return input;
}

/**
 * @param {CohortOption[]} options
 * @returns {Record<string, string | number | null>}
 */
function optionValues(options) {
  /** @type {Record<string, string | number | null>} */
  const out = {};
  for (const o of options) {
    const raw = /** @type {HTMLInputElement | HTMLSelectElement} */ (document.getElementById(`opt-${o.name}`)).value.trim();
    if (o.choices || o.type === "string") out[o.name] = raw;
    else out[o.name] = raw === "" ? null : Number(raw);
  }
  return out;
}

/**
 * @param {HTMLElement} main
 * @param {(() => void)[]} stops the page's cleanup functions
 */
async function formPage(main, stops) {
  /** @type {[import("./types").Page<any>, CohortOption[], import("./types").Page<CohortResultOut>]} */
  const [page, options, previous] = await Promise.all([
    api(`/api/recordings${qs({ limit: 500 })}`),
    api("/api/cohorts/options"),
    api(`/api/cohorts${qs({ limit: 20 })}`),
  ]);
  const recs = page.items;
  const mode = h("select", { id: "cohort-mode", "aria-label": "How recordings are grouped" },
    h("option", { value: "condition" }, "by their condition"),
    h("option", { value: "named" }, "into named groups"));
  const groupNames = h("input", { id: "group-names", value: "A, B", "aria-label": "Group names, comma-separated" });
  const namesBox = h("div", { class: "row", hidden: true }, h("label", { for: "group-names", style: "margin:0" }, "Groups"), groupNames, h("span", { class: "small muted" }, "comma-separated; then pick each recording's group"));
  const tbody = h("tbody", { id: "cohort-recordings" });
  const error = h("div", { id: "cohort-error" });
  const progress = h("div", { id: "cohort-progress" });
  const submit = h("button", { type: "submit", class: "primary", id: "cohort-submit" }, "Compare groups");
  const label = h("input", { id: "cohort-label", maxlength: "200", placeholder: "optional" });

  const names = () => [...new Set(groupNames.value.split(",").map((s) => s.trim()).filter(Boolean))];
  function rows() {
    clear(tbody);
    const named = mode.value === "named";
    namesBox.hidden = !named;
    if (!recs.length) tbody.append(h("tr", {}, h("td", { colspan: "5", class: "muted" }, "No recordings yet: upload some on the Recordings page, each with its condition.")));
    for (const r of recs) {
      let pick;
      if (named) {
        pick = h("select", { class: "group-pick", dataset: { id: String(r.id) }, "aria-label": `Group of recording ${r.id}` },
          h("option", { value: "" }, "— left out"), names().map((n) => h("option", { value: n }, n)));
      } else {
        pick = h("input", { type: "checkbox", class: "group-pick", checked: Boolean(r.condition), disabled: !r.condition, dataset: { id: String(r.id) }, "aria-label": `Include recording ${r.id}` });
      }
      tbody.append(h("tr", { dataset: { id: String(r.id) } },
        h("td", {}, pick),
        h("td", { class: "mono" }, r.id),
        h("td", {}, r.label ? h("strong", {}, r.label, " ") : null, r.subject || h("span", { class: "muted" }, "–")),
        h("td", {}, r.condition || h("span", { class: "muted", title: "set it on the recording's page" }, "no condition")),
        h("td", { class: "mono small" }, r.file_names.join(", "))));
    }
  }
  mode.addEventListener("change", rows);
  groupNames.addEventListener("change", rows);

  function body() {
    /** @type {{ label: string | null, options: Record<string, unknown>, group_by?: string, recording_ids?: number[], groups?: Record<string, number[]> }} */
    const out = { label: label.value.trim() || null, options: optionValues(options) };
    if (mode.value === "condition") {
      out.group_by = "condition";
      // Oldest first: the groups come in the order their first recording does.
      out.recording_ids = [.../** @type {NodeListOf<HTMLInputElement>} */ (tbody.querySelectorAll("input.group-pick:checked"))].map((c) => Number(c.dataset.id)).sort((x, y) => x - y);
      return out;
    }
    /** @type {Record<string, number[]>} */
    const groups = {};
    for (const s of /** @type {NodeListOf<HTMLSelectElement>} */ (tbody.querySelectorAll("select.group-pick"))) if (s.value) (groups[s.value] ||= []).push(Number(s.dataset.id));
    out.groups = groups;
    return out;
  }

  /** @param {SubmitEvent} e */
  async function onSubmit(e) {
    e.preventDefault();
    clear(error);
    clear(progress);
    submit.disabled = true;
    try {
      const job = await api("/api/cohorts", { method: "POST", body: body() });
      const bar = h("div", {});
      const line = h("div", { class: "small muted", id: "cohort-progress-text" }, "queued");
      progress.append(h("div", { class: "progress", role: "progressbar" }, bar), line);
      const follower = followJob(job, (j) => {
        bar.style.width = `${Math.round(100 * j.progress)}%`;
        line.textContent = j.state === "running" ? `${j.message} (${j.done} of ${j.of})` : j.state;
      });
      stops.push(follower.stop);
      const final = await follower.done;
      if (final.state === "succeeded") location.hash = `#/cohort/${job.id}`;
      else progress.append(banner("error", final.error || `The comparison ${final.state}.`));
    } catch (err) {
      error.append(banner("error", inFormWords(err, FIELD_WORDS)));
    } finally {
      submit.disabled = false;
    }
  }

  rows();
  main.append(
    h("div", { class: "page-head" }, h("h1", {}, "Cohort"), h("span", { class: "muted small" }, "Compare conditions: every recording analysed alone, measured, summarised per group and tested between groups.")),
    h("form", { class: "card", id: "cohort-form", onsubmit: onSubmit, novalidate: true },
      h("h2", {}, "Recordings"),
      h("div", { class: "row" }, h("label", { for: "cohort-mode", style: "margin:0" }, "Group the recordings"), mode),
      namesBox,
      h("div", { class: "table-wrap", style: "margin-top:8px" },
        h("table", {}, h("thead", {}, h("tr", {}, ["Use", "#", "Subject", "Condition", "Files"].map((c) => h("th", {}, c)))), tbody)),
      h("h2", {}, "Options"),
      h("div", { class: "fields" },
        options.map((o) => h("div", {}, h("label", { for: `opt-${o.name}` }, o.name.replaceAll("_", " "), o.unit ? h("span", { class: "hint" }, ` [${o.unit}]`) : null), optionInput(o), h("div", { class: "small muted" }, o.help))),
        h("div", {}, h("label", { for: "cohort-label" }, "Label"), label)),
      h("div", { class: "row", style: "margin-top:14px" }, submit),
      error, progress),
    // With no earlier comparison there is no card (append() would write null as "null").
    previousCard(previous.items) ?? "");
}

/** @param {CohortResultOut[]} items */
function previousCard(items) {
  if (!items.length) return null;
  return h("section", { class: "card" }, h("h2", {}, "Earlier comparisons"),
    h("ul", { id: "cohort-list" }, items.map((c) => h("li", {},
      h("a", { href: `#/cohort/${c.id}` }, `Cohort #${c.id}`), c.label ? ` “${c.label}”` : "", " ", tag(c.job.state),
      h("span", { class: "small muted" }, ` ${Object.entries(c.groups).map(([g, ids]) => `${g} (${ids.length})`).join(" vs ")} · ${when(c.job.created_at)}`)))));
}

// ---- the result --------------------------------------------------------------------------

/**
 * @param {HTMLElement} main
 * @param {number} id the comparison's id
 * @param {(() => void)[]} stops the page's cleanup functions
 */
async function resultPage(main, id, stops) {
  const head = h("div", { class: "page-head" }, h("div", {}, h("a", { href: "#/cohort", class: "small" }, "← New comparison"), h("h1", {}, `Cohort #${id}`)));
  const body = h("div", { id: "cohort-result" });
  main.append(head, body);
  /** @type {CohortResultOut} */
  let out = await api(`/api/cohorts/${id}`);
  if (out.job.state !== "succeeded") {
    const line = h("p", { class: "muted", id: "cohort-progress-text" }, out.job.message);
    body.append(line);
    if (out.job.state === "queued" || out.job.state === "running") {
      const follower = followJob(out.job, (j) => (line.textContent = `${j.state}: ${j.message} (${j.done} of ${j.of})`));
      stops.push(follower.stop);
      await follower.done;
      out = await api(`/api/cohorts/${id}`);
    }
    if (out.job.state !== "succeeded") {
      clear(body).append(banner("error", out.job.error || `This comparison ${out.job.state}.`));
      return;
    }
    clear(body);
  }
  const r = /** @type {CohortResult} */ (out.result); // set once the job succeeded
  const groups = Object.keys(r.groups);
  const colour = Object.fromEntries(groups.map((g, i) => [g, PALETTE[i % PALETTE.length]]));
  head.append(h("div", { class: "actions" }, h("a", { class: "button", id: "cohort-csv", href: `/api/cohorts/${id}/csv`, download: `cohort-${id}.csv` }, "Download CSV (one row per recording)")));
  if (out.label) /** @type {HTMLElement} */ (head.querySelector("h1")).append(` “${out.label}”`);
  body.append(
    h("p", { class: "small muted" }, `${groups.map((g) => `${g}: ${r.groups[g].n} recording(s)`).join(" · ")}. ${r.subject_rule}.`),
    ...r.pairings.map((p) => h("p", { class: "small" }, `${p.groups[0]} vs ${p.groups[1]}: ${p.why}`)),
    groupCard(r, groups),
    testsCard(r),
    plotsCard(r),
    orderCard(r, groups),
    r.warnings.length ? h("details", { class: "card" }, h("summary", {}, `${r.warnings.length} warning(s) from the analysis`), h("ul", {}, r.warnings.map((w) => h("li", { class: "small" }, w)))) : "");
  drawPlots(r, groups, colour);
}

/** @type {(r: CohortResult, m: string) => string} */
const unitOf = (r, m) => (r.units[m] ? ` [${r.units[m]}]` : "");

/**
 * @param {CohortResult} r
 * @param {string[]} groups
 */
function groupCard(r, groups) {
  const measures = Object.keys(r.units);
  return h("section", { class: "card" }, h("h2", {}, "Groups"),
    h("div", { class: "table-wrap" }, h("table", { id: "cohort-groups" },
      h("thead", {}, h("tr", {}, h("th", {}, "Measure"), groups.map((g) => h("th", {}, `${g} (n = ${r.groups[g].n})`)))),
      h("tbody", {}, measures.map((m) => h("tr", {},
        h("td", { class: "mono small" }, m + unitOf(r, m)),
        groups.map((g) => {
          const s = r.groups[g].measures[m];
          if (!s || s.n === 0) return h("td", { class: "muted small" }, `no value${s && s.missing ? ` (${s.missing} missing)` : ""}`);
          return h("td", { class: "small" },
            h("div", {}, `${fmt(s.mean)} ± ${s.sd === null ? "–" : fmt(s.sd)}`),
            h("div", { class: "muted" }, `median ${fmt(s.median)} [${fmt(s.q1)}, ${fmt(s.q3)}]`),
            h("div", { class: "muted" }, `n ${s.n}${s.missing ? `, ${s.missing} missing` : ""}`));
        })))))));
}

/** @param {CohortResult} r */
function testsCard(r) {
  const c = r.correction;
  return h("section", { class: "card" }, h("h2", {}, "Tests between groups"),
    h("p", { class: "small", id: "cohort-correction" }, `Correction: ${c.statement}.`),
    h("div", { class: "table-wrap" }, h("table", { id: "cohort-tests" },
      h("thead", {}, h("tr", {}, ["Measure", "Groups", "Test", "Statistic", "p", `p (${c.method})`, "Effect", "Why this test"].map((x) => h("th", {}, x)))),
      h("tbody", {}, r.tests.map((t) => h("tr", { class: t.significant ? "significant" : "" },
        h("td", { class: "mono small" }, t.measure),
        h("td", { class: "small" }, `${t.groups[0]} vs ${t.groups[1]} (${t.design}, n ${t.n.join("/")})`),
        t.skipped
          ? h("td", { colspan: "6", class: "muted small test-skipped" }, `not tested: ${t.skipped}`)
          // A tested comparison (no `skipped`) names its test and effect.
          : [h("td", {}, TEST_WORDS[/** @type {string} */ (t.test)] || t.test),
            h("td", { class: "num" }, fmt(t.statistic)),
            h("td", { class: "num p-value" }, fmt(t.p, 3)),
            h("td", { class: "num p-adjusted" }, h("strong", {}, fmt(t.p_adjusted, 3)), t.significant ? " *" : ""),
            h("td", { class: "small" }, `${EFFECT_WORDS[/** @type {string} */ (t.effect_name)] || t.effect_name || ""} ${fmt(t.effect, 3)}`),
            h("td", { class: "small muted" }, t.rule)]))))),
    h("p", { class: "small muted" }, `* adjusted p < ${c.alpha}. Effects: the first group minus the second.`));
}

/** @param {CohortResult} r */
function plotsCard(r) {
  const measures = Object.keys(r.units);
  return h("section", { class: "card" }, h("h2", {}, "Per recording, per group"),
    h("p", { class: "small muted" }, "Each point is one recording; the box is its group's median and quartiles."),
    h("div", { class: "grid-plots", id: "cohort-plots" }, measures.map((m) => h("div", { class: "plot cohort-plot", id: `plot-${m}`, dataset: { measure: m } }))));
}

/**
 * @param {CohortResult} r
 * @param {string[]} groups
 * @param {Record<string, string>} colour per group
 */
function drawPlots(r, groups, colour) {
  for (const m of Object.keys(r.units)) {
    const traces = groups.map((g) => {
      const members = r.recordings.filter((x) => x.group === g && x.measures[m] !== null && x.measures[m] !== undefined);
      return {
        type: "box", name: g, y: members.map((x) => x.measures[m]), text: members.map((x) => `${x.source} (${x.subject})`),
        boxpoints: "all", jitter: 0.4, pointpos: 0, marker: { color: colour[g], size: 7 }, line: { color: colour[g] },
        hovertemplate: "%{text}: %{y}<extra></extra>",
      };
    });
    const div = document.getElementById(`plot-${m}`);
    if (div) draw(div, traces, layout({ title: { text: m + unitOf(r, m), font: { size: 12 } }, showlegend: false, hovermode: "closest", height: 260 }));
  }
}

/**
 * @param {CohortResult} r
 * @param {string[]} groups
 */
function orderCard(r, groups) {
  return h("section", { class: "card" }, h("h2", {}, "Onset order"),
    h("div", { class: "table-wrap" }, h("table", { id: "cohort-orders" },
      h("thead", {}, h("tr", {}, ["Group", "Most common (recordings)", "Most common (lifts)", "Mean onset [s]"].map((x) => h("th", {}, x)))),
      h("tbody", {}, groups.map((g) => {
        const o = r.groups[g].activation_order;
        return h("tr", {},
          h("td", {}, g),
          h("td", { class: "small" }, o.most_common.length ? `${o.most_common.join(" > ")} (${o.count} of ${o.n})` : h("span", { class: "muted" }, "no order (fewer than two muscles with onsets)")),
          h("td", { class: "small" }, o.lifts.most_common.length ? `${o.lifts.most_common.join(" > ")} (${o.lifts.count} of ${o.lifts.n})` : "–"),
          h("td", { class: "small" }, Object.entries(o.mean_onset_s).sort((a, b) => a[1] - b[1]).map(([k, v]) => `${k} ${fmt(v, 3)}`).join(", ") || "–"));
      })))));
}
