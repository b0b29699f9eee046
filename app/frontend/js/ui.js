// Small DOM helpers and number formatting shared by the pages.

/**
 * Create an element: h("div", {class: "x", onclick: fn}, child, "text", ...).
 * @template {keyof HTMLElementTagNameMap} K
 * @param {K} tag
 * @param {Record<string, any> | null} [attrs] attributes; `on...` functions are listeners,
 *   `class`, `dataset` and `html` set those; true is an empty attribute, null/false none
 * @param {...any} children nodes, text, or (nested) arrays of them; null/false are skipped
 * @returns {HTMLElementTagNameMap[K]}
 */
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k.startsWith("on") && typeof v === "function") el.addEventListener(k.slice(2), v);
    else if (k === "class") el.className = v;
    else if (k === "dataset") Object.assign(el.dataset, v);
    else if (k === "html") el.innerHTML = v;
    else if (v === true) el.setAttribute(k, "");
    else el.setAttribute(k, v);
  }
  for (const child of children.flat(Infinity)) {
    if (child === null || child === undefined || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

/**
 * Remove every child of `el`.
 * @template {Node} E
 * @param {E} el
 * @returns {E}
 */
export function clear(el) {
  while (el.firstChild) el.removeChild(el.firstChild);
  return el;
}

/**
 * A number with about 4 significant digits; null as an en dash.
 * @param {unknown} value
 * @param {number} [digits]
 * @returns {string}
 */
export function fmt(value, digits = 4) {
  if (value === null || value === undefined || Number.isNaN(value)) return "–";
  if (typeof value !== "number") return String(value);
  if (value === 0) return "0";
  const a = Math.abs(value);
  if (a >= 1e5 || a < 1e-3) return value.toExponential(digits - 1);
  return Number(value.toPrecision(digits)).toLocaleString("en-US", { maximumFractionDigits: 6 });
}

/**
 * A signed percentage with one decimal ("+12.3 %"); null as an en dash.
 * @param {number | null | undefined} value [%]
 * @returns {string}
 */
export function pct(value) {
  if (value === null || value === undefined || Number.isNaN(value)) return "–";
  const s = value > 0 ? "+" : "";
  return `${s}${value.toFixed(1)} %`;
}

/**
 * @param {number} n a size [B]
 * @returns {string}
 */
export function bytes(n) {
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${(n / 1024).toFixed(1)} KB`;
  return `${(n / 1024 / 1024).toFixed(1)} MB`;
}

/**
 * @param {string | null | undefined} iso an ISO 8601 time
 * @returns {string}
 */
export function when(iso) {
  if (!iso) return "–";
  const d = new Date(iso);
  return d.toLocaleString(undefined, { dateStyle: "medium", timeStyle: "short" });
}

/**
 * @param {string} kind "error", "info", "ok", ...
 * @param {string | Node} text
 * @returns {HTMLDivElement}
 */
export function banner(kind, text) {
  return h("div", { class: `banner ${kind}`, role: kind === "error" ? "alert" : "status" }, text);
}

/**
 * @param {string} state
 * @returns {HTMLSpanElement}
 */
export function tag(state) {
  return h("span", { class: `tag ${state}` }, state);
}

/**
 * Message of an error for the user: the server's detail when there is one.
 * @param {any} err what was caught
 * @returns {string}
 */
export function messageOf(err) {
  if (err && err.problem) {
    const p = err.problem;
    return p.detail || p.title || err.message;
  }
  return err && err.message ? err.message : String(err);
}

/**
 * `text` as a literal pattern for a RegExp.
 * @param {string} text
 */
function literal(text) {
  return String(text).replace(/[.*+?^${}()|[\]\\]/g, "\\$&");
}

/**
 * Every error of an API refusal in a form's words, one {field, label, text} per field: a
 * request the schema refuses lists them all (`problem.errors`, first message per field), any
 * other refusal names one. `words` maps request field names (the part before any ".index") to
 * the form's labels; field names inside a message are put in the form's words too.
 * @param {any} err what was caught
 * @param {Record<string, string>} words
 * @returns {{ field: string | null, label: string | null, text: string }[]}
 */
export function errorsInFormWords(err, words) {
  /** @type {import("./types").Problem} */
  const p = (err && err.problem) || {};
  const listed = Array.isArray(p.errors) && p.errors.length ? p.errors : [{ field: p.field, message: null }];
  /** @type {Map<string, import("./types").ProblemError>} */
  const seen = new Map();
  for (const e of listed) {
    const key = e.field ? String(e.field).split(".")[0] : "";
    if (!seen.has(key)) seen.set(key, e);
  }
  return [...seen.entries()].map(([key, e]) => {
    const label = key ? words[key] : null;
    let text = e.message === null || e.message === undefined ? messageOf(err) : String(e.message);
    if (e.field) text = text.replace(new RegExp(`^${literal(e.field)}(?::|\\b)\\s*`), "");
    text = namesInFormWords(text, words);
    const where = e.field && e.field !== key ? ` (${e.field.slice(key.length + 1).split(".").map((i) => `item ${Number(i) + 1}`).join(", ")})` : "";
    if (label) return { field: key, label, text: text.startsWith(label) ? text : `${label}${where}: ${text}` };
    return { field: key || null, label: null, text: e.field && e.message !== null && e.message !== undefined ? `${e.field}: ${text}` : text };
  });
}

/**
 * An API error in a form's words: "Duration: must be > 0" rather than "duration: ...";
 * several errors of one request together, separated by "; ".
 * @param {any} err what was caught
 * @param {Record<string, string>} words
 * @returns {string}
 */
export function inFormWords(err, words) {
  return errorsInFormWords(err, words).map((e) => e.text).join("; ");
}

/**
 * An API refusal shown on a form: every error at once in the form's words, in `box` (brought
 * into view below the sticky top bar), and each beside its field when `fields` maps the request
 * field to its input (marked aria-invalid until the next try).
 * @param {HTMLElement} box
 * @param {any} err what was caught
 * @param {Record<string, string>} words
 * @param {Record<string, HTMLInputElement | HTMLSelectElement | HTMLTextAreaElement | null | undefined>} [fields]
 */
export function showFormErrors(box, err, words, fields = {}) {
  clearFieldErrors(fields);
  const errors = errorsInFormWords(err, words);
  const shown = errors.length > 1
    ? h("div", { class: "banner error", role: "alert" }, h("strong", {}, `${errors.length} fields need a change:`), h("ul", { class: "form-errors" }, errors.map((e) => h("li", {}, e.text))))
    : banner("error", errors[0].text);
  box.append(shown);
  let first = null;
  for (const e of errors) {
    const input = e.field ? fields[e.field] : null;
    if (!input) continue;
    const folded = input.closest("details");
    if (folded) folded.open = true; // a field in a folded section is shown with its message
    input.setAttribute("aria-invalid", "true");
    input.after(h("div", { class: "field-error", role: "alert", dataset: { field: e.field } }, e.text));
    first = first || input;
  }
  shown.scrollIntoView({ block: "nearest" });
  if (first && !inView(first)) first.scrollIntoView({ block: "center" });
}

/**
 * The marks of `showFormErrors` taken off the fields.
 * @param {Record<string, HTMLElement | null | undefined>} fields
 */
export function clearFieldErrors(fields) {
  for (const input of Object.values(fields)) {
    if (!input) continue;
    input.removeAttribute("aria-invalid");
    const next = input.nextElementSibling;
    if (next && next.classList.contains("field-error")) next.remove();
  }
}

/** @param {Element} el */
function inView(el) {
  const r = el.getBoundingClientRect();
  return r.top >= 60 && r.bottom <= window.innerHeight;
}

/** @type {Promise<Record<string, Record<string, { maximum?: number, minimum?: number, exclusiveMaximum?: number, exclusiveMinimum?: number }>>> | null} */
let capsLoading = null;

/** The server's bounds of the fields the pages fill (GET /api/caps), fetched once. */
export function loadCaps() {
  if (!capsLoading) {
    capsLoading = fetch("/api/caps", { headers: { Accept: "application/json" } })
      .then((r) => (r.ok ? r.json() : {}))
      .catch(() => ({}));
  }
  return capsLoading;
}

/**
 * Each capped field shows its cap, as this server enforces it: the input's min/max, and a hint
 * ("max 400") added to its label. `form` names the request (plan, simulation, sweep, upload,
 * analysis, recording_patch); `fields` maps request fields to inputs.
 * @param {string} form
 * @param {Record<string, HTMLInputElement | null | undefined>} fields
 */
export async function showCaps(form, fields) {
  const caps = (await loadCaps())[form] || {};
  for (const [field, input] of Object.entries(fields)) {
    const c = caps[field];
    if (!input || !c) continue;
    const max = c.maximum ?? c.exclusiveMaximum;
    const min = c.minimum ?? c.exclusiveMinimum;
    if (max !== undefined) input.max = String(max);
    if (min !== undefined) input.min = String(min);
    const sel = `label[for="${input.id}"]`;
    const label = input.id ? (input.parentElement && input.parentElement.querySelector(sel)) || document.querySelector(sel) : null;
    if (!label || max === undefined || label.querySelector(".cap")) continue;
    label.append(h("span", { class: "hint cap", dataset: { field } }, ` max ${c.exclusiveMaximum !== undefined ? `< ${fmt(max)}` : fmt(max)}`));
  }
}

/**
 * A message that names request fields (`frame_rate`) in a form's words (“Frame rate”).
 * @param {unknown} text
 * @param {Record<string, string>} words
 * @returns {string}
 */
export function namesInFormWords(text, words) {
  let out = String(text);
  for (const [field, label] of Object.entries(words)) {
    if (field.includes("_")) out = out.replace(new RegExp(`(?:the )?\\b${field}\\b(?: option)?`, "g"), `the “${label}” field`);
  }
  return out;
}

/**
 * `fn` called once calls stop for `ms`, with the last call's arguments.
 * @template {unknown[]} A
 * @param {(...args: A) => void} fn
 * @param {number} ms [ms]
 * @returns {(...args: A) => void}
 */
export function debounce(fn, ms) {
  /** @type {ReturnType<typeof setTimeout> | undefined} */
  let t = undefined;
  return (...args) => {
    clearTimeout(t);
    t = setTimeout(() => fn(...args), ms);
  };
}

export const DEG = 180 / Math.PI;
