// The REST API: JSON requests, problem+json errors, uploads with progress, job events.

import { isTerminal } from "./names.js";

const TOKEN_KEY = "bioplan.token";

export function token() {
  return localStorage.getItem(TOKEN_KEY) || "";
}

/** @param {string} value */
export function setToken(value) {
  if (value) localStorage.setItem(TOKEN_KEY, value);
  else localStorage.removeItem(TOKEN_KEY);
}

/** An API failure: the server's problem (status, title, detail, field, file). */
export class ApiError extends Error {
  /**
   * @param {number} status HTTP status
   * @param {import("./types").Problem} problem
   */
  constructor(status, problem) {
    super(problem.detail || problem.title || `HTTP ${status}`);
    this.status = status;
    this.problem = problem;
  }
}

/** @returns {Record<string, string>} */
function authHeaders() {
  const t = token();
  return t ? { Authorization: `Bearer ${t}` } : {};
}

/**
 * @param {Response} response
 * @returns {Promise<import("./types").Problem>}
 */
async function problemOf(response) {
  let body = null;
  try {
    body = await response.json();
  } catch {
    body = null;
  }
  if (body && typeof body === "object") return body;
  return { status: response.status, title: response.statusText, detail: `HTTP ${response.status}` };
}

/**
 * GET/POST/DELETE JSON; throws ApiError with the server's message.
 * @param {string} path
 * @param {{ method?: string, body?: unknown, signal?: AbortSignal }} [options] `body` is sent as JSON
 * @returns {Promise<any>} the JSON answer (null for 204)
 */
export async function api(path, { method = "GET", body, signal } = {}) {
  /** @type {Record<string, string>} */
  const headers = { Accept: "application/json", ...authHeaders() };
  /** @type {RequestInit} */
  const init = { method, headers, signal };
  if (body !== undefined) {
    headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const response = await fetch(path, init);
  if (!response.ok) {
    if (response.status === 401) document.dispatchEvent(new CustomEvent("bioplan:unauthorized"));
    throw new ApiError(response.status, await problemOf(response));
  }
  if (response.status === 204) return null;
  return response.json();
}

/**
 * Query string from an object, skipping null/undefined; arrays repeat the key.
 * @param {Record<string, any>} params
 * @returns {string}
 */
export function qs(params) {
  const q = new URLSearchParams();
  for (const [k, v] of Object.entries(params)) {
    if (v === null || v === undefined || v === "") continue;
    if (Array.isArray(v)) v.forEach((x) => q.append(k, x));
    else q.append(k, v);
  }
  const s = q.toString();
  return s ? `?${s}` : "";
}

/**
 * POST multipart form data with upload progress (fetch cannot report it; XHR can).
 * onProgress(fraction) is called while the body is sent. Resolves with the JSON body,
 * rejects with ApiError (the server's problem) or a network Error.
 * @param {string} path
 * @param {FormData} form
 * @param {(fraction: number) => void} [onProgress]
 * @returns {Promise<any>} the JSON answer
 */
export function upload(path, form, onProgress) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", path);
    const auth = authHeaders();
    for (const [k, v] of Object.entries(auth)) xhr.setRequestHeader(k, v);
    xhr.setRequestHeader("Accept", "application/json");
    xhr.upload.onprogress = (e) => {
      if (e.lengthComputable && onProgress) onProgress(e.loaded / e.total);
    };
    xhr.onload = () => {
      let body = null;
      try {
        body = JSON.parse(xhr.responseText);
      } catch {
        body = null;
      }
      if (xhr.status >= 200 && xhr.status < 300) resolve(body);
      else {
        if (xhr.status === 401) document.dispatchEvent(new CustomEvent("bioplan:unauthorized"));
        reject(new ApiError(xhr.status, body || { status: xhr.status, detail: xhr.statusText || `HTTP ${xhr.status}` }));
      }
    };
    xhr.onerror = () => reject(new Error("the upload failed: the server could not be reached"));
    xhr.send(form);
  });
}

/**
 * Follow a job's Server-Sent Events until it ends. onUpdate(job) for every update.
 * Returns a function that stops listening. Resolves `done` with the final job.
 * @param {{ id: number, events_url: string }} job
 * @param {(job: import("./types").JobInfo) => void} onUpdate
 * @returns {{ done: Promise<import("./types").JobInfo>, stop(): void }}
 */
export function followJob(job, onUpdate) {
  // Set as the promise starts (synchronously), before anything reads it.
  let source = /** @type {EventSource} */ (/** @type {unknown} */ (null));
  let stopped = false;
  const done = new Promise((resolve) => {
    source = new EventSource(job.events_url);
    /**
     * @param {MessageEvent} event
     * @param {boolean} final
     */
    const handle = (event, final) => {
      const data = JSON.parse(event.data);
      onUpdate(data);
      if (final) {
        source.close();
        resolve(data);
      }
    };
    source.addEventListener("progress", (e) => handle(e, false));
    source.addEventListener("done", (e) => handle(e, true));
    source.onerror = async () => {
      // An ended stream (idle, a server restart) is reopened by the browser itself. A refused
      // one (429: too many streams, a proxy) is closed: read the job every few seconds instead.
      while (!stopped && source.readyState === EventSource.CLOSED) {
        try {
          const now = await api(`/api/jobs/${job.id}`);
          onUpdate(now);
          if (isTerminal(now.state)) {
            resolve(now);
            return;
          }
        } catch {
          /* keep the last state shown */
        }
        await new Promise((wake) => setTimeout(wake, 3000));
      }
    };
  });
  return {
    done,
    stop() {
      stopped = true;
      if (source) source.close();
    },
  };
}
