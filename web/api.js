// The API client. Every request carries the bearer token the sign-in URL brought; images and
// the SSE stream are fetched with that header too (EventSource and <img src> cannot send it),
// so the token never appears in a URL.

import { state } from "./state.js";

export const TOKEN_KEY = "photonbox-token";

/// What to do when the server refuses the token (app.js signs out).
let unauthorized = () => {};

export function onUnauthorized(handler) {
  unauthorized = handler;
}

export class ApiError extends Error {
  constructor(status, body) {
    super((body && body.error) || `HTTP ${status}`);
    this.status = status;
    this.path = body && body.path;
  }
}

export async function api(path, opts = {}) {
  const headers = Object.assign({}, opts.headers, { Authorization: `Bearer ${state.token}` });
  const r = await fetch(path, Object.assign({}, opts, { headers }));
  if (r.status === 401) {
    unauthorized();
  }
  return r;
}

export async function apiJson(path, opts = {}) {
  const r = await api(path, opts);
  let body = null;
  if (r.status !== 204) {
    try { body = await r.json(); } catch (_) { body = null; }
  }
  if (!r.ok) throw new ApiError(r.status, body);
  return body;
}

/// Each integrator's defaults, as the server's spec has them (its OpenAPI document's
/// `Params` schema, `x-defaults`): the form shows them and never writes them itself.
export async function specDefaults() {
  const r = await fetch("/api/openapi.json");
  if (!r.ok) throw new ApiError(r.status, null);
  const doc = await r.json();
  return doc.components.schemas.Params["x-defaults"];
}

/// Show an image the API serves (it needs the Authorization header) in `img`.
export async function loadImage(img, path, signal) {
  const r = await api(path, { signal, cache: "no-store" });
  if (!r.ok) return false;
  const url = URL.createObjectURL(await r.blob());
  await new Promise((resolve) => {
    img.onload = img.onerror = resolve;
    const old = img.dataset.objectUrl;
    img.src = url;
    img.dataset.objectUrl = url;
    if (old) URL.revokeObjectURL(old);
  });
  img.hidden = false;
  return img.naturalWidth > 0;
}

/// Follow a job's Server-Sent Events through fetch (so that it carries the token), calling
/// `onEvent(name, data)` for each until the stream ends or `signal` aborts.
export async function followEvents(id, onEvent, signal) {
  const r = await api(`/api/jobs/${id}/events`, {
    signal, headers: { Accept: "text/event-stream" },
  });
  if (!r.ok || !r.body) return;
  const reader = r.body.pipeThrough(new TextDecoderStream()).getReader();
  let buf = "";
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buf += value.replace(/\r\n?/g, "\n");
    let end;
    while ((end = buf.indexOf("\n\n")) >= 0) {
      const block = buf.slice(0, end);
      buf = buf.slice(end + 2);
      let name = "", data = "";
      for (const line of block.split("\n")) {
        if (line.startsWith("event:")) name = line.slice(6).trim();
        else if (line.startsWith("data:")) data += line.slice(5).trim();
      }
      if (name) {
        let parsed = null;
        try { parsed = JSON.parse(data); } catch (_) { parsed = null; }
        onEvent(name, parsed);
      }
    }
  }
}

/// Keep the token of a sign-in URL (`?token=`) and drop it from the address bar.
export function takeTokenFromUrl() {
  const params = new URLSearchParams(location.search);
  const t = params.get("token");
  if (t) {
    localStorage.setItem(TOKEN_KEY, t);
    params.delete("token");
    const rest = params.toString();
    history.replaceState(null, "", location.pathname + (rest ? `?${rest}` : "") + location.hash);
  }
}
