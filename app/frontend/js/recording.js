// Recording detail: raw EMG and envelopes with onsets, arm angles and velocities, lifts with
// their A/B/C phases, the human template. Zooming fetches the window again (server-side
// min/max downsampling), so long recordings stay light.

import { ApiError, api, followJob, qs } from "./api.js";
import { names } from "./names.js";
import { draw, layout, phaseFill, phaseLegend, plotly } from "./plots.js";
import { IMAGE_SIZE_NOTE, channelsCard, checksCard, framesCard, imageSizeFix, optionsCard } from "./recording_panels.js";
import { banner, bytes, clear, debounce, fmt, h, messageOf, when } from "./ui.js";

/** @typedef {import("./types").RecordingChannel} RecordingChannel */
/** @typedef {import("./types").JobInfo} JobInfo */
/**
 * A recording as GET /api/recordings/{id} answers (no response model yet: read untyped).
 * @typedef {any} RecordingDetail
 */

const POINTS = 1600;
// Channels mapped to a site take the site's colour (app/names.py); the others these.
/** The shading of a lift's rising part where it has no phases (no elbow angle). */
const RISING_FILL = "rgba(110,119,129,0.10)";

// Channels without a site: hues away from the phases' green, orange and blue (as the sites').
const EXTRA_COLORS = ["#6e7781", "#4d2d8c", "#e85aad", "#3d444d", "#7a6a00"];

/**
 * An onset order in muscle names: channels without a site are counted, not listed.
 * @param {string[] | null | undefined} order channel or muscle names, first onset first
 * @returns {string}
 */
export function orderText(order) {
  const sites = (order || []).filter((name) => name in names.muscle_colours);
  const others = (order || []).length - sites.length;
  const more = others ? ` (+${others} channel${others > 1 ? "s" : ""} without a muscle site)` : "";
  return sites.length ? `${sites.join(" → ")}${more}` : others ? `no muscle site mapped${more}` : "–";
}

/**
 * Whether a template is the paper's default rather than this person's lifts.
 * @param {{ is_paper_default?: boolean | null, source?: string | null }} template
 * @returns {boolean}
 */
function isPaperDefault(template) {
  return template.is_paper_default ?? /^paper default/i.test(template.source || "");
}

/**
 * The factor and unit EMG is shown in.
 * @param {string | null | undefined} unit the reader's unit
 */
function emgScale(unit) {
  // Readers deliver EMG in volts; microvolts read better.
  return unit === "V" ? { k: 1e6, unit: "µV" } : { k: 1, unit: unit || "" };
}

/**
 * @param {string} name a muscle site or channel name
 * @param {number} i the channel's place (colours of channels without a site)
 * @returns {string}
 */
function muscleColor(name, i) {
  return names.muscle_colours[name] || EXTRA_COLORS[i % EXTRA_COLORS.length];
}

/**
 * Rectangles [x0, x1] x [y0, y1] as one filled trace (null-separated polygons). A few traces
 * draw far faster than layout shapes: a 10-minute session has over a thousand phase and onset
 * rectangles, which as shapes cost Plotly about half a second per plot.
 * @param {Iterable<[number, number]>} spans [x0, x1] each [s]
 * @param {number} y0
 * @param {number} y1
 * @param {Record<string, unknown>} style more of the trace (axes, name, fill colour)
 * @returns {Record<string, any>} a Plotly trace
 */
function rectTrace(spans, y0, y1, style) {
  /** @type {(number | null)[]} */
  const x = [];
  /** @type {(number | null)[]} */
  const y = [];
  for (const [a, b] of spans) {
    x.push(a, b, b, a, a, null);
    y.push(y0, y0, y1, y1, y0, null);
  }
  return { x, y, type: "scatter", mode: "lines", fill: "toself", line: { width: 0 }, hoverinfo: "skip", showlegend: false, ...style };
}

/**
 * The A/B/C phases (or the rising part when a lift has none) and lift tops on one subplot.
 * @param {any[]} lifts the analysis's lifts (times [s])
 * @param {[number, number]} span the subplot's y range
 * @param {{ xaxis: string, yaxis: string }} axes
 * @returns {Record<string, any>[]} Plotly traces
 */
function liftTraces(lifts, [y0, y1], axes) {
  /** @type {Map<string, [number, number][]>} */
  const spans = new Map();
  /** @type {(key: string, a: number, b: number) => number} */
  const add = (key, a, b) => /** @type {[number, number][]} */ (spans.get(key) || spans.set(key, []).get(key)).push([a, b]);
  /** @type {{ x: (number | null)[], y: (number | null)[] }} */
  const tops = { x: [], y: [] };
  for (const lift of lifts) {
    if (lift.phases.length) lift.phases.forEach((/** @type {any} */ p) => add(p.name, p.start_s, p.end_s));
    else add("rising", lift.start_s, lift.top_s);
    tops.x.push(lift.top_s, lift.top_s, null);
    tops.y.push(y0, y1, null);
  }
  const traces = [...spans].map(([name, list]) => rectTrace(list, y0, y1, { ...axes, name: `phase ${name}`, fillcolor: names.phases.some((p) => p.name === name) ? phaseFill(name) : name === "rising" ? RISING_FILL : "rgba(0,0,0,0.04)" }));
  if (lifts.length) traces.push({ ...tops, ...axes, type: "scatter", mode: "lines", name: "lift tops", line: { color: "#9ca3af", width: 1, dash: "dot" }, hoverinfo: "skip", showlegend: false });
  return traces;
}

/** [min, max] of the finite values of several series (null when there is none). */
/**
 * @param {...(number | null)[]} series
 * @returns {[number, number] | null} the smallest and largest finite value, null without one
 */
function extent(...series) {
  let lo = Infinity;
  let hi = -Infinity;
  for (const ys of series) for (const v of ys) if (v !== null && Number.isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; }
  return lo <= hi ? [lo, hi] : null;
}

/**
 * The channels' ids, file by file: a change that reads the files again replaces them.
 * @param {RecordingDetail} rec
 * @returns {string}
 */
function channelKey(rec) {
  return rec.files.map((/** @type {any} */ f) => `${f.id}:${f.channels.map((/** @type {any} */ c) => c.id).join(",")}`).join(";");
}

/**
 * The page. A change that reads the files again (the EMG rate's fix, the channels' mapping, a
 * video's landmarks stored) gives the channels new ids: the page is then drawn again in place
 * from the new recording, following the job that re-analyses it.
 * @param {HTMLElement} main
 * @param {Array<string | undefined>} match the recording's id
 */
export async function render(main, [idText]) {
  const id = Number(idText);
  /** @type {(() => void)[]} */
  const stops = [];
  let shown = 0;
  /**
   * @param {RecordingDetail | null} [rec] the recording as it is now (null: read it)
   * @param {JobInfo | null} [follow] a job to follow
   * @param {string | null} [notice] what to say at the top
   */
  async function show(rec = null, follow = null, notice = null) {
    const mine = ++shown;
    stops.splice(0).forEach((f) => f());
    const y = window.scrollY;
    let fresh = rec;
    if (!fresh) {
      try {
        fresh = await api(`/api/recordings/${id}`);
      } catch (err) {
        clear(main).append(banner("error", messageOf(err)), h("a", { href: "#/recordings" }, "← All recordings"));
        return;
      }
    }
    if (mine !== shown) return;
    clear(main);
    // Drawn again after a change: where the user was stays in view.
    await recordingPage(main, fresh, { stops, follow, notice, refresh: show, restore: rec ? y : 0 });
  }
  await show();
  return () => stops.forEach((f) => f());
}

/**
 * The recording's condition (a cohort groups by it), changed in place without re-analysing.
 * @param {RecordingDetail} rec
 */
function conditionEditor(rec) {
  const input = h("input", { id: "rec-condition", maxlength: "100", value: rec.condition || "", placeholder: "none (e.g. heavy)", "aria-label": "Condition", style: "max-width:220px" });
  const from = rec.options && rec.options.condition_from;
  // Filled from the file names or a BIDS sidecar at upload: say so, so it can be checked.
  const status = h("span", { class: "small muted", id: "rec-condition-status" }, from ? `from ${from}` : "");
  /** @param {SubmitEvent} e */
  async function save(e) {
    e.preventDefault();
    try {
      const now = await api(`/api/recordings/${rec.id}`, { method: "PATCH", body: { condition: input.value, analyse: false } });
      input.value = now.condition || "";
      status.textContent = now.condition ? `saved: ${now.condition}` : "saved: no condition";
    } catch (err) {
      status.textContent = messageOf(err);
    }
  }
  return h("form", { class: "row small", id: "condition-form", onsubmit: save },
    h("label", { for: "rec-condition", style: "margin:0" }, "Condition"), input,
    h("button", { type: "submit", class: "small" }, "Save"), status,
    h("a", { href: "#/cohort", class: "small" }, "compare conditions →"));
}

/**
 * How the page is drawn: its cleanup functions, a job to follow, a notice, the redraw and the
 * scroll position to restore.
 * @typedef {{ stops: (() => void)[], follow: JobInfo | null, notice: string | null,
 *   refresh: (rec?: RecordingDetail | null, follow?: JobInfo | null, notice?: string | null) => Promise<void>,
 *   restore: number }} PageContext
 */

/**
 * @param {HTMLElement} main
 * @param {RecordingDetail} rec
 * @param {PageContext} ctx
 */
async function recordingPage(main, rec, ctx) {
  const id = rec.id;
  /** @type {{ window: [number | null, number | null], analysis: any, emgChannels: RecordingChannel[], stop: any }} */
  const state = { window: [null, null], analysis: null, emgChannels: [], stop: ctx.stops };
  /** @type {RecordingChannel[]} */
  const channels = rec.files.flatMap((/** @type {any} */ f) => f.channels.map((/** @type {any} */ c) => ({ ...c, file: f.original_name })));
  const allEmg = channels.filter((c) => c.kind === "emg");
  // Shown at first: the channels mapped to the method's four sites (or the first six).
  const mapped = allEmg.filter((c) => c.site);
  state.emgChannels = mapped.length ? mapped : allEmg.slice(0, 6);
  const duration = Math.max(0, ...channels.map((c) => c.start + c.duration));

  // ---- header and files -----------------------------------------------------------------
  const title = [rec.subject, rec.task].filter(Boolean).join(" · ") || rec.file_names.join(", ");
  const analysisStatus = h("div", { id: "analysis-status" });
  const analyseButton = h("button", { type: "button", onclick: () => runAnalysis() }, "Run analysis job");
  main.append(
    h("div", { class: "page-head" },
      h("div", {},
        h("a", { href: "#/recordings", class: "small" }, "← All recordings"),
        h("h1", {}, `Recording #${rec.id}: ${title}`),
        h("div", { class: "muted small" }, `${rec.load_kg !== null ? `${rec.load_kg} kg · ` : ""}${fmt(duration, 4)} s · uploaded ${when(rec.created_at)}`),
      ),
      h("div", { class: "actions" }, analyseButton),
    ),
    analysisStatus,
  );
  main.append(conditionEditor(rec));
  if (rec.notes) main.append(h("p", { class: "muted" }, rec.notes));

  const fileRows = channels.map((c) =>
    h("tr", {},
      h("td", { class: "mono" }, c.file),
      h("td", {}, c.name),
      h("td", {}, c.kind),
      h("td", {}, c.site || h("span", { class: "muted" }, "–")),
      h("td", { class: "num" }, `${fmt(c.rate)} Hz`),
      h("td", { class: "num" }, c.n_samples.toLocaleString("en-US")),
      h("td", { class: "num" }, `${fmt(c.duration)} s`),
      h("td", {}, c.unit),
    ));
  const filesCard = h("details", { class: "card" },
    h("summary", {}, `${rec.files.length} file(s), ${channels.length} channel(s): ${rec.files.map((/** @type {any} */ f) => `${f.original_name} (${f.format}, ${bytes(f.size)})`).join(", ")}`),
    h("div", { class: "table-wrap", style: "margin-top:8px" },
      h("table", {}, h("thead", {}, h("tr", {}, ["File", "Channel", "Kind", "Site", "Rate", "Samples", "Duration", "Unit"].map((c, i) => h("th", { class: [4, 5, 6].includes(i) ? "num" : "" }, c)))), h("tbody", {}, fileRows)),
    ),
  );
  main.append(filesCard);
  // A change that re-analyses hands its job here: the page follows it and redraws. A change
  // that read the files again (`changed`: the recording as it is now) redraws the whole page.
  /** @type {(job: JobInfo, changed?: RecordingDetail | null, notice?: string | null) => unknown} */
  const onJob = (job, changed = null, notice = null) =>
    changed && channelKey(changed) !== channelKey(rec) ? ctx.refresh(changed, job, notice) : runAnalysis(job);
  main.append(.../** @type {HTMLElement[]} */ ([
    checksCard(rec, onJob), framesCard(rec), channelsCard(rec, onJob),
    optionsCard(rec, { phase_bounds_deg: names.phase_bounds_deg }, onJob),
  ].filter(Boolean)));

  // ---- plot cards --------------------------------------------------------------------
  const emgDiv = h("div", { class: "plot tall", id: "emg-plot" });
  /** @type {HTMLDivElement & Partial<Pick<PlotlyElement, "on">>} once drawn, Plotly's */
  const angleDiv = h("div", { class: "plot", id: "angle-plot" });
  const templateDiv = h("div", { class: "plot", id: "template-plot" });
  const analysisNote = h("div", { id: "analysis-note" }, h("p", { class: "muted small" }, "Analysing the recording (envelopes, onsets, angles, lifts)…"));
  const liftsBox = h("div", { id: "lifts" });
  const templateFacts = h("div", { class: "facts", id: "template-facts" });
  const legend = h("div", { class: "legend-inline", id: "emg-legend" },
    phaseLegend(),
    h("span", {}, h("span", { class: "swatch", style: `background:${RISING_FILL}` }), "rising (a lift without phases: no elbow angle)"),
    h("span", {}, h("span", { class: "swatch onset-swatch" }), "onsets: a bar along the top, in the muscle's colour"),
    h("span", {}, "· drag to zoom, double-click to reset; zooming loads the window at full detail"),
  );
  const picker = h("details", { class: "small", id: "channel-picker" },
    h("summary", {}, `EMG channels shown: ${state.emgChannels.length} of ${allEmg.length}`),
    h("div", { class: "row", style: "margin-top:6px" }, allEmg.map((c) =>
      h("label", { class: "nowrap", style: "font-weight:400; margin:0 10px 0 0" },
        h("input", { type: "checkbox", checked: state.emgChannels.includes(c), dataset: { channel: String(c.id) }, onchange: (/** @type {Event} */ e) => {
          state.emgChannels = allEmg.filter((x) => x === c ? /** @type {HTMLInputElement} */ (e.target).checked : state.emgChannels.includes(x));
          /** @type {HTMLElement} */ (picker.querySelector("summary")).textContent = `EMG channels shown: ${state.emgChannels.length} of ${allEmg.length}`;
          reload();
        } }),
        ` ${c.name}${c.site ? ` (${c.site})` : ""}`))),
  );
  main.append(
    h("section", { class: "card" }, h("h2", {}, "EMG: raw signal and envelope, onsets, lifts"), legend, allEmg.length > state.emgChannels.length || allEmg.length > 1 ? picker : null, analysisNote, emgDiv),
    h("section", { class: "card" }, h("h2", {}, "Shoulder and elbow flexion"), angleDiv),
    h("div", { class: "grid-2" },
      h("section", { class: "card" }, h("h2", {}, "Human template"), templateFacts, templateDiv),
      h("section", { class: "card" }, h("h2", {}, "Lifts and phases"), liftsBox),
    ),
  );
  if (!allEmg.length) emgDiv.replaceWith(h("p", { class: "muted" }, "This recording has no EMG channels."));

  // ---- data ----------------------------------------------------------------------------
  async function fetchRaw() {
    if (!state.emgChannels.length) return null;
    const [t0, t1] = state.window;
    return api(`/api/recordings/${id}/signals${qs({ channel: state.emgChannels.map((c) => c.id), points: POINTS, t0, t1 })}`);
  }
  async function fetchAnalysis() {
    const [t0, t1] = state.window;
    return api(`/api/viewer/recordings/${id}/analysis${qs({ points: POINTS, t0, t1 })}`);
  }

  function range() {
    const [t0, t1] = state.window;
    return t0 === null ? undefined : [t0, t1];
  }

  /** The lifts to shade on a file's panel: separate trials have their own clocks, so a
   * file's panels show its own lifts only (recorded together, every lift is on the one clock).
   * @param {any} analysis the analysis overlays
   * @param {string | undefined} file
   * @returns {any[]}
   */
  function liftsOf(analysis, file) {
    if (rec.session !== "separate" || !file) return analysis.lifts;
    return analysis.lifts.filter((/** @type {any} */ l) => !l.file || l.file === file);
  }

  /**
   * @param {any} raw GET /api/recordings/{id}/signals: the shown channels' samples
   * @param {any} analysis the analysis overlays, or null
   */
  async function drawEmg(raw, analysis) {
    if (!raw) {
      if (allEmg.length && window.Plotly) window.Plotly.purge(emgDiv);
      return;
    }
    const n = raw.channels.length;
    /** @type {Record<string, any>[]} */
    const under = [];
    /** @type {Record<string, any>[]} */
    const traces = [];
    /** @type {Record<string, any>} */
    const lay = layout({ height: Math.max(260, 150 * n + 60), showlegend: true, uirevision: "emg", hovermode: "x", margin: { l: 78, r: 12, t: 30, b: 40 } });
    const gap = 0.04;
    // Separate trials keep their own clocks: a file's panels share a time axis with each other
    // only, and the last of them says whose clock it is.
    /** @param {{ channel_id: number }} ch */
    const fileOf = (ch) => state.emgChannels.find((c) => c.id === ch.channel_id)?.file;
    const files = raw.channels.map(fileOf);
    const ownClocks = rec.session === "separate" && new Set(files).size > 1;
    /** @param {number} i */
    const firstOf = (i) => (ownClocks ? files.indexOf(files[i]) : 0);
    /** @param {number} i */
    const lastOf = (i) => (ownClocks ? files.lastIndexOf(files[i]) : n - 1);
    // Vertical room: a small gap between panels, more where one file's clock ends (its ticks).
    /** @param {number} i */
    const sepAfter = (i) => (i === n - 1 ? 0 : ownClocks && i === lastOf(i) ? 0.45 : gap);
    const total = raw.channels.reduce((/** @type {number} */ sum, /** @type {unknown} */ _, /** @type {number} */ i) => sum + 1 + sepAfter(i), 0);
    /** @type {[number, number][]} */
    const domains = [];
    raw.channels.reduce((/** @type {number} */ top, /** @type {unknown} */ _, /** @type {number} */ i) => {
      domains.push([Math.max(0, top - 1 / total), top]);
      return top - (1 + sepAfter(i)) / total;
    }, 1);
    lay.height += 60 * (new Set(files).size - 1) * (ownClocks ? 1 : 0);
    const envs = analysis ? analysis.emg : [];
    // Files of one session often share channel names: a panel takes its own file's envelope.
    /** @param {{ name: string, file?: string }} ch */
    const envOf = (ch) => {
      const named = envs.filter((/** @type {any} */ e) => e.channel === ch.name);
      const mine = named.find((/** @type {any} */ e) => e.file === ch.file);
      // Analyses that name files otherwise (or not at all): a name that is unique still fits.
      return mine || (named.length === 1 && !envs.some((/** @type {any} */ e) => e.file === ch.file) ? named[0] : undefined);
    };
    raw.channels.forEach((/** @type {any} */ ch, /** @type {number} */ i) => {
      const axis = i === 0 ? "" : String(i + 1);
      const axes = { xaxis: `x${axis}`, yaxis: `y${axis}` };
      /** @type {Partial<RecordingChannel>} */
      const info = state.emgChannels.find((c) => c.id === ch.channel_id) || {};
      const scale = emgScale(ch.unit);
      const s = ch.series[0];
      const env = envOf(ch);
      const label = info.site || (env ? env.muscle : ch.name);
      const color = muscleColor(label, i);
      const rawY = s.y.map((/** @type {number | null} */ v) => (v === null ? null : v * scale.k));
      traces.push({ x: s.t, y: rawY, type: "scatter", mode: "lines", name: `${ch.name} raw`, line: { color: "#b6bcc6", width: 1 }, ...axes, showlegend: false, hoverinfo: "skip" });
      const es = env ? emgScale(env.unit) : null;
      const envY = env && es ? env.envelope.y.map((/** @type {number | null} */ v) => (v === null ? null : v * es.k)) : [];
      if (env) traces.push({ x: env.envelope.t, y: envY, type: "scatter", mode: "lines", name: `${ch.name} envelope${label !== ch.name ? ` (${label})` : ""}`, line: { color, width: 2 }, ...axes });
      const span = extent(rawY, envY);
      if (analysis && span) {
        // Shading first, so that the signals are drawn over it.
        under.push(...liftTraces(liftsOf(analysis, info.file), span, axes));
        if (env && env.onsets.length) {
          const top = span[1] - 0.1 * (span[1] - span[0]);
          under.push(rectTrace(env.onsets, top, span[1], { ...axes, name: `${label} onsets`, fillcolor: color, opacity: 0.45 }));
        }
      }
      const [bottom, top] = domains[i];
      lay[`yaxis${axis}`] = { domain: [bottom, top], title: { text: `${ch.name.length > 14 ? `${ch.name.slice(0, 13)}…` : ch.name}<br>${label !== ch.name ? `${label} ` : ""}[${scale.unit}]`, font: { size: 10.5 } }, gridcolor: "#eceff3", zeroline: false };
      const first = firstOf(i);
      const xTitle = ownClocks ? `t [s] in ${files[i]} (its own clock)` : "t [s]";
      lay[`xaxis${axis}`] = { anchor: `y${axis}`, matches: i === first ? undefined : `x${first === 0 ? "" : first + 1}`, showticklabels: i === lastOf(i), gridcolor: "#eceff3", range: range(), title: i === lastOf(i) ? { text: xTitle, font: { size: 11 } } : undefined };
    });
    await draw(emgDiv, [...under, ...traces], lay);
    emgDiv.style.minHeight = "0";
    hook(emgDiv);
  }

  /** @param {any} analysis the analysis overlays, or null */
  async function drawAngles(analysis) {
    if (!analysis || !analysis.angles) {
      angleDiv.style.minHeight = "0";
      clear(angleDiv).append(h("p", { class: "muted" }, analysis ? "No shoulder or elbow angle in this recording (EMG only): lifts come from EMG bursts." : "Waiting for the analysis…"));
      return;
    }
    const a = analysis.angles;
    /**
     * @param {{ t: number[], y: (number | null)[] }} s
     * @param {string} name
     * @param {string} color
     * @param {string} axis
     * @param {string} [dash]
     */
    const line = (s, name, color, axis, dash) => ({ x: s.t, y: s.y, type: "scatter", mode: "lines", name, line: { color, width: 2, dash }, xaxis: "x", yaxis: axis });
    const traces = [
      line(a.elbow_deg, "elbow flexion", "#cf222e", "y"),
      line(a.shoulder_deg, "shoulder flexion", "#8250df", "y"),
      line(a.elbow_velocity_deg_s, "elbow velocity", "#cf222e", "y2", "dot"),
      line(a.shoulder_velocity_deg_s, "shoulder velocity", "#8250df", "y2", "dot"),
    ];
    const under = [];
    const angles = extent(a.elbow_deg.y, a.shoulder_deg.y);
    const velocities = extent(a.elbow_velocity_deg_s.y, a.shoulder_velocity_deg_s.y);
    const angleLifts = liftsOf(analysis, a.file);
    if (angles) under.push(...liftTraces(angleLifts, angles, { xaxis: "x", yaxis: "y" }));
    if (velocities) under.push(...liftTraces(angleLifts, velocities, { xaxis: "x", yaxis: "y2" }));
    const lay = layout({ height: 400, uirevision: "angles", hovermode: "x" });
    lay.xaxis = { anchor: "y2", range: range(), title: { text: "t [s]" }, gridcolor: "#eceff3" };
    lay.yaxis = { domain: [0.53, 1], title: { text: "angle [deg]" }, gridcolor: "#eceff3" };
    lay.yaxis2 = { domain: [0, 0.47], title: { text: "velocity [deg/s]" }, gridcolor: "#eceff3", zerolinecolor: "#c9ced6" };
    if (!angleDiv.on) clear(angleDiv);
    angleDiv.style.minHeight = "";
    await draw(angleDiv, [...under, ...traces], lay);
    hook(angleDiv);
  }

  /**
   * @param {any} template the analysis's human template
   * @param {any[]} lifts
   */
  async function drawTemplate(template, lifts) {
    const T = template;
    const paperDefault = isPaperDefault(T);
    clear(templateFacts).append(
      fact("template from", paperDefault ? "the paper's default (no lifts with kinematics from this person)" : `this person's lifts: ${T.source}`),
      fact("velocity peak at (per lift)", T.peak_velocity_angle_deg === null ? "–" : `${fmt(T.peak_velocity_angle_deg, 3)}°${paperDefault ? " (paper)" : T.n_lifts === 1 ? " (from one lift: no spread)" : ` ± ${fmt(T.peak_velocity_angle_sd_deg, 2)}° (mean ± SD of each lift's own peak angle)`}`),
      // What a plan uses (issue 29): the same fraction of the robot's elbow stroke, so a plan's
      // template angle differs from the per-lift mean when the stroke is not the lifts' range.
      ...(paperDefault || T.peak_velocity_range_fraction === null || T.peak_velocity_range_fraction === undefined ? []
        : [fact("plans place the peak at", `${Math.round(100 * T.peak_velocity_range_fraction)} % of the elbow stroke (where these lifts peak within their own range; a plan's template angle is that point of the robot's stroke)`)]),
      fact("lifts", `${lifts.length} found, ${paperDefault ? 0 : T.n_lifts} with kinematics`),
      fact("peak at", T.peak_velocity_time_fraction === null ? "–" : `${Math.round(100 * T.peak_velocity_time_fraction)} % of the lift`),
      fact("activation order", orderText(T.activation_order)),
    );
    if (!T.normalized_time || !T.normalized_time.length) {
      clear(templateDiv).append(h("p", { class: "muted small" }, `${T.source}: no kinematic profile; the planner uses the paper's defaults (velocity peak at 62°).`));
      return;
    }
    const x = T.normalized_time.map((/** @type {number} */ v) => 100 * v);
    /**
     * @param {number[]} mean
     * @param {number[]} sd
     * @param {string} color "rgba(r,g,b,1)"
     * @param {string} name
     * @param {string} axis
     */
    const band = (mean, sd, color, name, axis) => [
      { x, y: mean.map((m, i) => m + sd[i]), mode: "lines", line: { width: 0 }, showlegend: false, hoverinfo: "skip", yaxis: axis },
      { x, y: mean.map((m, i) => m - sd[i]), mode: "lines", line: { width: 0 }, fill: "tonexty", fillcolor: color.replace("1)", "0.18)"), name: `${name} ± SD`, hoverinfo: "skip", yaxis: axis },
      { x, y: mean, mode: "lines", line: { color, width: 2 }, name: `${name} (mean)`, yaxis: axis },
    ];
    const traces = [
      ...band(T.velocity_mean, T.velocity_sd, "rgba(207,34,46,1)", "elbow velocity", "y"),
      ...band(T.acceleration_mean, T.acceleration_sd, "rgba(37,99,235,1)", "elbow acceleration", "y2"),
    ];
    /** @type {Record<string, any>} */
    const lay = layout({ height: 400, hovermode: "x", legend: { orientation: "h", y: -0.22, x: 0 }, margin: { l: 56, r: 12, t: 10, b: 40 } });
    lay.xaxis = { title: { text: "lift [% of the concentric part]", standoff: 4 }, anchor: "y2", gridcolor: "#eceff3" };
    lay.yaxis = { domain: [0.54, 1], title: { text: "velocity / peak" }, gridcolor: "#eceff3" };
    lay.yaxis2 = { domain: [0, 0.46], title: { text: "accel. / peak" }, gridcolor: "#eceff3" };
    clear(templateDiv);
    await draw(templateDiv, traces, lay);
  }

  /** @param {HTMLElement} div a plot drawn by `draw` */
  function hook(div) {
    // Zoom on either plot loads that window at full detail into both.
    if (div.dataset.hooked) return;
    div.dataset.hooked = "1";
    /** @type {PlotlyElement} */ (div).on("plotly_relayout", onRelayout);
  }

  /**
   * @param {string} k
   * @param {string} v
   */
  function fact(k, v) {
    return h("div", { class: "fact" }, h("div", { class: "k" }, k), h("div", { class: "v" }, v));
  }

  /** @param {any} analysis the analysis overlays */
  function drawLifts(analysis) {
    clear(liftsBox);
    liftsBox.dataset.analysis = String(analysis.analysis_id);
    // Every warning is shown, and first: with a wrong EMG rate "No lift found" alone misleads.
    // The rate's own warning is said once, with its fix, in the data checks above.
    const rc = rec.rate_check;
    const rateNote = rc ? `The EMG rate of ${rc.file} looks wrong: see “Data checks” above for its one-click fix.` : null;
    /** @type {string[]} */
    const notes = [...new Set(analysis.warnings.map((/** @type {string} */ w) => (rc && w.includes(rc.reason) ? rateNote : w)))];
    if (notes.length) {
      liftsBox.append(h("div", { class: "banner warn", id: "analysis-warnings", role: "status" },
        h("strong", {}, `${notes.length} note(s) from the analysis`),
        h("ul", { class: "small" }, notes.map((w) => h("li", {}, IMAGE_SIZE_NOTE.test(w) ? imageSizeFix(rec, w, onJob) : w)))));
    }
    if (!analysis.lifts.length) {
      liftsBox.append(h("p", { class: "muted", id: "no-lifts" }, "No lift found."));
      return;
    }
    /**
     * @param {any} lift
     * @param {string} name a phase
     */
    const dur = (lift, name) => {
      const p = lift.phases.find((/** @type {any} */ x) => x.name === name && x.part !== "eccentric");
      return p ? fmt(p.end_s - p.start_s, 3) : "–";
    };
    // A session of several files: one running number, and the file (with its own lift number).
    const files = new Set(analysis.lifts.map((/** @type {any} */ l) => l.file).filter(Boolean));
    const many = files.size > 1;
    const head = ["#", ...(many ? ["file"] : []), "start [s]", "top [s]", "end [s]", "A [s]", "B [s]", "C [s]", "v-peak [deg]", "onset order"];
    liftsBox.append(
      h("div", { class: "table-wrap" },
        h("table", { id: "lifts-table" },
          h("thead", {}, h("tr", {}, head.map((c) => h("th", { class: c.includes("[") ? "num" : "" }, c)))),
          h("tbody", {}, analysis.lifts.map((/** @type {any} */ l, /** @type {number} */ k) =>
            h("tr", { dataset: { file: l.file || "" } },
              h("td", {}, `${many ? k + 1 : l.index}`, h("div", { class: "small muted" }, l.source)),
              many ? h("td", { class: "mono small" }, l.file, h("div", { class: "small muted" }, `lift ${l.index} of this file`)) : null,
              h("td", { class: "num" }, fmt(l.start_s)),
              h("td", { class: "num" }, fmt(l.top_s)),
              h("td", { class: "num" }, fmt(l.end_s)),
              h("td", { class: "num" }, dur(l, "A")),
              h("td", { class: "num" }, dur(l, "B")),
              h("td", { class: "num" }, dur(l, "C")),
              h("td", { class: "num" }, fmt(l.peak_velocity_angle_deg, 3)),
              h("td", { class: "small" }, orderText(l.activation_order)),
            ))),
        ),
      ),
    );
  }

  // The overlays come from the newest finished analysis job; "ready" once one was loaded,
  // "waiting" while a job runs, "failed" when the last one failed (the button runs it again).
  let analysisState = "unknown";
  async function load({ initial = false } = {}) {
    const rawPromise = fetchRaw();
    const analysisPromise = analysisState === "ready" || analysisState === "unknown"
      ? fetchAnalysis().catch((err) => {
        noAnalysis(err);
        return null;
      })
      : Promise.resolve(null);
    // Both arrive in a fraction of a second (the overlays are stored by the analysis job):
    // draw each plot once, with its overlays.
    const [raw, analysis] = await Promise.all([rawPromise, analysisPromise]);
    await drawEmg(raw, analysis || state.analysis);
    if (!analysis) return;
    const first = state.analysis === null || state.analysis.analysis_id !== analysis.analysis_id;
    analysisState = "ready";
    state.analysis = analysis;
    clear(analysisNote);
    await drawAngles(analysis);
    if (initial || first) {
      await drawTemplate(analysis.template, analysis.lifts);
      drawLifts(analysis);
    }
  }

  /** No overlays yet (409): follow the running job, report the failed one, or start one. */
  /** @param {any} err what loading the overlays threw */
  function noAnalysis(err) {
    const job = err instanceof ApiError && err.status === 409 ? err.problem.job : undefined;
    if (job === undefined) {
      analysisState = "failed";
      clear(analysisNote).append(banner("warn", `The analysis of this recording could not be loaded: ${messageOf(err)}`));
      clear(angleDiv).append(h("p", { class: "muted" }, "No analysis: raw signals only."));
      return;
    }
    if (job && job.state !== "queued" && job.state !== "running") {
      analysisState = "failed";
      clear(analysisNote).append(banner("warn", `${messageOf(err)}. Raw signals only; “Run analysis job” tries again.`));
      clear(angleDiv).append(h("p", { class: "muted" }, "No analysis: raw signals only."));
      return;
    }
    analysisState = "waiting";
    if (job && job.id === following) return; // followed already (handed over by a change)
    clear(analysisNote).append(h("p", { class: "muted small" }, job
      ? `Analysis job #${job.id} is ${job.state}: envelopes, onsets, angles and lifts appear when it ends.`
      : "This recording has not been analysed yet: starting the analysis job…"));
    runAnalysis(job);
  }

  const reload = debounce(() => load().catch((err) => clear(analysisNote).append(banner("error", messageOf(err)))), 200);
  /** @param {Record<string, unknown>} ev Plotly's relayout: the changed layout keys */
  function onRelayout(ev) {
    const keys = Object.keys(ev);
    if (keys.some((k) => /^xaxis\d*\.autorange$/.test(k))) {
      if (state.window[0] === null) return;
      state.window = [null, null];
      reload();
      return;
    }
    const k0 = keys.find((k) => /^xaxis\d*\.range\[0\]$/.test(k));
    if (!k0) return;
    const t0 = Number(ev[k0]);
    const t1 = Number(ev[k0.replace("[0]", "[1]")]);
    if (!(t1 > t0)) return;
    state.window = [Math.max(0, t0), t1];
    reload();
  }

  /** Submit an analysis job (or follow `existing`), with its progress; then load its overlays. */
  /** @type {number | null} */
  let following = null;
  /** @param {{ id: number, state: string } | null} [existing] a job already running */
  async function runAnalysis(existing = null) {
    if (existing) following = existing.id;
    analyseButton.disabled = true;
    clear(analysisStatus);
    const bar = h("div", {});
    const text = h("span", { class: "small" }, "queued");
    analysisStatus.append(h("div", { class: "card" }, h("div", { class: "row" }, h("strong", {}, "Analysis job "), text), h("div", { class: "progress" }, bar)));
    try {
      const job = existing || await api("/api/analyses", { method: "POST", body: { recording_id: id } });
      const follow = followJob(job, (j) => {
        bar.style.width = `${Math.round(100 * j.progress)}%`;
        text.textContent = `#${j.id} ${j.state}: ${j.error || j.message}`;
      });
      state.stop.push(follow.stop);
      const final = await follow.done;
      if (final.state === "succeeded") {
        /** @type {HTMLElement} */ (bar.parentElement).classList.add("done");
        // A video's landmarks stored (a pose job) add channels: the page is drawn again.
        const now = await api(`/api/recordings/${id}`);
        if (channelKey(now) !== channelKey(rec)) {
          ctx.refresh(now);
          return;
        }
        if (final.kind !== "pose") text.append(" · ", h("a", { href: `#/plan?analysis=${final.id}` }, "plan with this template"));
        analysisState = "unknown";
        await load({ initial: true });
      } else {
        /** @type {HTMLElement} */ (bar.parentElement).classList.add("failed");
        analysisState = "failed";
        clear(analysisNote).append(banner("warn", `Analysis job #${final.id} ${final.state}: ${final.error || final.message}`));
      }
    } catch (err) {
      clear(analysisStatus).append(banner("error", messageOf(err)));
    } finally {
      analyseButton.disabled = false;
    }
  }

  // Analyses already run on this recording.
  api(`/api/analyses${qs({ state: "succeeded", recording_id: id, limit: 50 })}`).then((/** @type {import("./types").Page<any>} */ page) => {
    const mine = page.items;
    if (mine.length) {
      analysisStatus.append(h("p", { class: "small muted" }, "Finished analyses: ", mine.map((a, i) => [i ? ", " : "", h("a", { href: `#/plan?analysis=${a.id}` }, `#${a.id}`), (a.summary || {}).n_lifts === 0 ? h("span", { class: "muted" }, " (no lift found)") : null]), " (use as planning template)"));
    }
  }).catch(() => {});

  if (ctx.notice) analysisStatus.before(banner("info", ctx.notice));
  if (ctx.restore) window.scrollTo(0, ctx.restore);
  await plotly();
  if (ctx.follow) runAnalysis(ctx.follow);
  try {
    await load({ initial: true });
  } catch (err) {
    main.append(banner("error", messageOf(err)));
  }
}

