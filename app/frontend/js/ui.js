// Small DOM helpers and number formatting shared by the pages.

/** Create an element: h("div", {class: "x", onclick: fn}, child, "text", ...). */
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

export function clear(el) {
  while (el.firstChild) el.removeChild(el.firstChild);
  return el;
}

/** A number with about 4 significant digits; null as an en dash. */
export function fmt(value, digits = 4) {
  if (value === null || value === undefined || Number.isNaN(value)) return "–";
  if (typeof value !== "number") return String(value);
  if (value === 0) return "0";
  const a = Math.abs(value);
  if (a >= 1e5 || a < 1e-3) return value.toExponential(digits - 1);
  return Number(value.toPrecision(digits)).toLocaleString("en-US", { maximumFractionDigits: 6 });
}

export function pct(value) {
  if (value === null || value === undefined || Number.isNaN(value)) return "–";
  const s = value > 0 ? "+" : "";
  return `${s}${value.toFixed(1)} %`;
}

export function bytes(n) {
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${(n / 1024).toFixed(1)} KB`;
  return `${(n / 1024 / 1024).toFixed(1)} MB`;
}

export function when(iso) {
  if (!iso) return "–";
  const d = new Date(iso);
  return d.toLocaleString(undefined, { dateStyle: "medium", timeStyle: "short" });
}

export function banner(kind, text) {
  return h("div", { class: `banner ${kind}`, role: kind === "error" ? "alert" : "status" }, text);
}

export function tag(state) {
  return h("span", { class: `tag ${state}` }, state);
}

/** Message of an error for the user: the server's detail when there is one. */
export function messageOf(err) {
  if (err && err.problem) {
    const p = err.problem;
    return p.detail || p.title || err.message;
  }
  return err && err.message ? err.message : String(err);
}

/** An API error in a form's words: "Duration: must be > 0" rather than "duration: ...".
 * `words` maps request field names (the part before any ".index") to the form's labels. */
export function inFormWords(err, words) {
  const field = err && err.problem && err.problem.field;
  const label = field && words[field.split(".")[0]];
  const text = messageOf(err);
  return label && !text.startsWith(label) ? `${label}: ${text.replace(new RegExp(`^${field}:\\s*`), "")}` : text;
}

/** A message that names request fields (`frame_rate`) in a form's words (“Frame rate”). */
export function namesInFormWords(text, words) {
  let out = String(text);
  for (const [field, label] of Object.entries(words)) {
    if (field.includes("_")) out = out.replace(new RegExp(`(?:the )?\\b${field}\\b(?: option)?`, "g"), `the “${label}” field`);
  }
  return out;
}

export function debounce(fn, ms) {
  let t = null;
  return (...args) => {
    clearTimeout(t);
    t = setTimeout(() => fn(...args), ms);
  };
}

export const DEG = 180 / Math.PI;
