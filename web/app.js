// photonbox gallery: plain JavaScript, no build step. Talks to the JSON API with the bearer
// token the sign-in URL carried; images and the SSE stream are fetched with that header too
// (EventSource and <img src> cannot send it), so the token never appears in a URL.
"use strict";

const TOKEN_KEY = "photonbox-token";
const $ = (id) => document.getElementById(id);

const state = {
  token: null,
  me: null,
  jobs: [],            // the last GET /api/jobs, newest first
  scenes: [],
  sceneSizes: new Map(), // built-in scene name -> [width, height]
  thumbs: new Map(),   // job id -> { key, url }
  galleryTimer: null,
  view: null,          // the AbortController of the open job or compare view
};

// ---------------------------------------------------------------- API

class ApiError extends Error {
  constructor(status, body) {
    super((body && body.error) || `HTTP ${status}`);
    this.status = status;
    this.path = body && body.path;
  }
}

async function api(path, opts = {}) {
  const headers = Object.assign({}, opts.headers, { Authorization: `Bearer ${state.token}` });
  const r = await fetch(path, Object.assign({}, opts, { headers }));
  if (r.status === 401) {
    signOut("That token was not accepted: sign in again.");
  }
  return r;
}

async function apiJson(path, opts = {}) {
  const r = await api(path, opts);
  let body = null;
  if (r.status !== 204) {
    try { body = await r.json(); } catch (_) { body = null; }
  }
  if (!r.ok) throw new ApiError(r.status, body);
  return body;
}

/// Show an image the API serves (it needs the Authorization header) in `img`.
async function loadImage(img, path, signal) {
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
async function followEvents(id, onEvent, signal) {
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

// ---------------------------------------------------------------- sign-in

function takeTokenFromUrl() {
  const params = new URLSearchParams(location.search);
  const t = params.get("token");
  if (t) {
    localStorage.setItem(TOKEN_KEY, t);
    params.delete("token");
    const rest = params.toString();
    history.replaceState(null, "", location.pathname + (rest ? `?${rest}` : "") + location.hash);
  }
}

function signOut(message) {
  localStorage.removeItem(TOKEN_KEY);
  state.token = null;
  state.me = null;
  state.jobs = [];
  for (const t of state.thumbs.values()) URL.revokeObjectURL(t.url);
  state.thumbs.clear();
  $("gallery").replaceChildren();
  $("me").textContent = "";
  $("sign-out").hidden = true;
  $("signin-error").textContent = message || "";
  showView("signin");
}

async function signIn() {
  state.token = localStorage.getItem(TOKEN_KEY);
  if (!state.token) {
    showView("signin");
    return;
  }
  try {
    state.me = await apiJson("/api/me");
  } catch (e) {
    if (e.status !== 401) signOut(`Could not reach the server: ${e.message}`);
    return;
  }
  $("me").textContent = `Signed in as ${state.me.name}${state.me.admin ? " (admin)" : ""}`;
  $("sign-out").hidden = false;
  try {
    state.scenes = (await apiJson("/api/scenes")).scenes;
  } catch (_) {
    state.scenes = [];
  }
  fillScenes();
  route();
}

// ---------------------------------------------------------------- views and routing

function showView(name) {
  for (const v of document.querySelectorAll(".view")) v.hidden = v.id !== `view-${name}`;
}

/// `#/` gallery, `#/job/ID`, `#/compare/A/B`.
function route() {
  if (!state.token || !state.me) return;
  if (state.view) state.view.abort();
  state.view = new AbortController();
  const parts = location.hash.replace(/^#\/?/, "").split("/").filter(Boolean);
  if (parts[0] === "job" && parts[1]) {
    stopGallery();
    openJob(Number(parts[1]), state.view.signal);
  } else if (parts[0] === "compare") {
    stopGallery();
    openCompare(Number(parts[1]) || null, Number(parts[2]) || null, state.view.signal);
  } else {
    showView("gallery");
    document.title = "photonbox: renders";
    startGallery();
  }
}

// ---------------------------------------------------------------- formatting

const PHASES = {
  photon_trace: "tracing photons", build_maps: "building photon maps",
  precompute: "precomputing irradiance", render: "camera pass", passes: "progressive passes",
};

function fmtSeconds(s) {
  if (s == null || !isFinite(s)) return "-";
  if (s < 1) return `${Math.round(s * 1000)} ms`;
  if (s < 90) return `${s.toFixed(s < 10 ? 1 : 0)} s`;
  if (s < 5400) return `${Math.round(s / 60)} min`;
  return `${(s / 3600).toFixed(1)} h`;
}

function fmtCount(n) {
  if (n == null) return "-";
  if (n >= 1e6) return `${+(n / 1e6).toFixed(2)}M`;
  if (n >= 1e3) return `${+(n / 1e3).toFixed(1)}k`;
  return String(n);
}

function fmtTime(t) {
  return t ? new Date(t * 1000).toLocaleString() : "-";
}

function integratorOf(job) {
  return (job.params && job.params.integrator) || "photon";
}

/// The parameters that matter most for what a job costs and shows.
function keyParams(job) {
  const p = job.params || {};
  const s = (job.stats && job.stats.params) || {};
  const w = p.width || s.width, h = p.height || s.height;
  const out = [];
  if (w && h) out.push(`${w}x${h}`);
  const integ = integratorOf(job);
  if (integ !== "raytrace") {
    if (p.photons != null) out.push(`${fmtCount(p.photons)} photons`);
    if (p.k != null) out.push(`k ${p.k}`);
  }
  if (integ === "ppm") out.push(`${p.iterations || 16} passes`);
  if (p.spp != null) out.push(`${p.spp} spp`);
  return out.join(", ");
}

function sceneOf(job) {
  return job.scene || "(uploaded scene)";
}

function duration(job) {
  if (job.started && job.finished) return job.finished - job.started;
  if (job.started) return Date.now() / 1000 - job.started;
  return null;
}

// ---------------------------------------------------------------- gallery

function startGallery() {
  stopGallery();
  const tick = async () => {
    await refreshGallery();
    // Faster while something renders; the list is served from memory.
    const busy = state.jobs.some((j) => j.status === "queued" || j.status === "running");
    state.galleryTimer = setTimeout(tick, busy ? 700 : 2500);
  };
  tick();
}

function stopGallery() {
  clearTimeout(state.galleryTimer);
  state.galleryTimer = null;
}

async function refreshGallery() {
  let jobs;
  try {
    jobs = (await apiJson("/api/jobs")).jobs;
  } catch (_) {
    return;
  }
  jobs.sort((a, b) => b.id - a.id);
  state.jobs = jobs;
  renderGallery();
  updateEstimate();
}

function renderGallery() {
  const list = $("gallery");
  const existing = new Map([...list.children].map((li) => [Number(li.dataset.jobId), li]));
  const seen = new Set();
  for (const job of state.jobs) {
    let li = existing.get(job.id);
    if (!li) li = makeCard(job);
    updateCard(li, job);
    list.appendChild(li); // moves it into newest-first order
    seen.add(job.id);
  }
  for (const [id, li] of existing) {
    if (!seen.has(id)) {
      li.remove();
      const t = state.thumbs.get(id);
      if (t) URL.revokeObjectURL(t.url);
      state.thumbs.delete(id);
    }
  }
  $("gallery-empty").hidden = state.jobs.length > 0;
  list.dataset.refreshes = String(Number(list.dataset.refreshes) + 1);
}

function makeCard(job) {
  const li = document.createElement("li");
  li.className = "card";
  li.dataset.jobId = job.id;
  li.innerHTML = `
    <a class="thumb-link"><img class="thumb" alt=""><span class="nothumb">no image yet</span></a>
    <div class="card-body">
      <h3><a class="title"></a></h3>
      <p class="meta params"></p>
      <p class="meta owner"></p>
      <p class="meta times"></p>
      <p class="status-line"><span class="status"></span>
        <progress class="mini" max="1" value="0" aria-hidden="true"></progress></p>
    </div>`;
  return li;
}

function updateCard(li, job) {
  const href = `#/job/${job.id}`;
  const label = `Job ${job.id}: ${sceneOf(job)}, ${integratorOf(job)}`;
  li.dataset.owner = job.owner || "";
  li.dataset.public = String(job.public);
  li.dataset.status = job.status;
  const link = li.querySelector(".thumb-link");
  link.href = href;
  link.tabIndex = -1; // the title link is the keyboard stop
  link.setAttribute("aria-hidden", "true");
  const title = li.querySelector(".title");
  title.href = href;
  title.textContent = `#${job.id} ${sceneOf(job)}`;
  li.querySelector(".params").textContent = `${integratorOf(job)}: ${keyParams(job)}`;
  li.querySelector(".owner").textContent =
    `${job.mine ? "yours" : `by ${job.owner}`} · ${job.public ? "public" : "private"}`;
  const d = duration(job);
  li.querySelector(".times").textContent =
    `submitted ${fmtTime(job.created)}${d != null ? ` · ${fmtSeconds(d)}` : ""}`;
  const status = li.querySelector(".status");
  status.textContent = job.status === "running" ? `running ${Math.round(job.progress * 100)}%`
    : job.status === "queued" && job.queue_position != null ? `queued (#${job.queue_position + 1})`
    : job.status;
  status.className = `status status-${job.status}`;
  const mini = li.querySelector(".mini");
  mini.value = job.progress || 0;
  mini.hidden = job.status !== "running";
  const img = li.querySelector(".thumb");
  img.alt = `Thumbnail of ${label}`;
  refreshThumb(li, job);
}

/// Fetch a card's image when it may have changed (a running ppm job publishes previews).
async function refreshThumb(li, job) {
  if (job.status === "queued") return;
  const key = `${job.status}:${Math.floor((job.progress || 0) * 20)}`;
  const have = state.thumbs.get(job.id);
  if (have && have.key === key) return;
  state.thumbs.set(job.id, { key, url: have ? have.url : "" });
  const img = li.querySelector(".thumb");
  const ok = await loadImage(img, `/api/jobs/${job.id}/image.png`);
  if (ok) {
    li.classList.add("has-thumb");
    state.thumbs.set(job.id, { key, url: img.dataset.objectUrl });
  }
}

// ---------------------------------------------------------------- submit form

/// Presets, per integrator: [photons, caustic photons, k, gather rays, spp, passes, scale of
/// the scene's own resolution].
const PRESETS = {
  draft: { photon: [50000, 50000, 30, 0, 1], ppm: [20000, 20000, 10, 0, 1, 8], raytrace: [0, 0, 0, 0, 1], scale: 0.5 },
  good: { photon: [200000, 200000, 50, 8, 4], ppm: [100000, 100000, 10, 0, 1, 32], raytrace: [0, 0, 0, 0, 4], scale: 1 },
  final: { photon: [1000000, 1000000, 100, 16, 16], ppm: [200000, 200000, 10, 0, 1, 256], raytrace: [0, 0, 0, 0, 16], scale: 2 },
};

function applyPreset(name) {
  const preset = PRESETS[name];
  const integ = $("integrator").value;
  const [photons, caustic, k, gather, spp, passes] = preset[integ];
  if (integ !== "raytrace") {
    $("photons").value = photons;
    $("caustic-photons").value = caustic;
    $("k").value = k;
    $("gather-rays").value = gather;
  }
  $("spp").value = spp;
  if (passes) $("iterations").value = passes;
  const [w, h] = sceneSize();
  $("width").value = Math.max(1, Math.round(w * preset.scale));
  $("height").value = Math.max(1, Math.round(h * preset.scale));
  for (const b of document.querySelectorAll("[data-preset]")) {
    b.setAttribute("aria-pressed", String(b.dataset.preset === name));
  }
  updateEstimate();
}

/// The chosen scene's own resolution (the camera's), 384x384 when unknown.
function sceneSize() {
  if (customScene()) {
    try {
      const cam = JSON.parse($("scene-json").value).camera;
      if (cam && cam.width && cam.height) return [cam.width, cam.height];
    } catch (_) { /* not valid JSON yet */ }
    return [384, 384];
  }
  return state.sceneSizes.get($("scene-name").value) || [384, 384];
}

function customScene() {
  return document.querySelector("input[name=scene-source]:checked").value === "custom";
}

function fillScenes() {
  const sel = $("scene-name");
  const prev = sel.value;
  sel.replaceChildren();
  for (const s of state.scenes) {
    const o = document.createElement("option");
    o.value = s.name;
    o.textContent = s.name;
    sel.appendChild(o);
  }
  if (prev && state.scenes.some((s) => s.name === prev)) sel.value = prev;
  else if (state.scenes.some((s) => s.name === "cornell")) sel.value = "cornell";
  onSceneChange();
}

async function onSceneChange() {
  const name = $("scene-name").value;
  const scene = state.scenes.find((s) => s.name === name);
  $("scene-description").textContent = (scene && scene.description) || "";
  if (name && !state.sceneSizes.has(name)) {
    try {
      const json = await apiJson(`/api/scenes/${encodeURIComponent(name)}`);
      state.sceneSizes.set(name, [json.camera.width, json.camera.height]);
    } catch (_) { /* keep the default */ }
  }
  updateEstimate();
}

function onIntegratorChange() {
  const integ = $("integrator").value;
  document.body.dataset.integrator = integ;
  for (const el of document.querySelectorAll(".ppm-only")) el.hidden = integ !== "ppm";
  for (const el of document.querySelectorAll(".photon-only")) el.hidden = integ === "raytrace";
  // The CLI's defaults for the new integrator.
  if (integ === "ppm") {
    $("photons").value = 100000; $("caustic-photons").value = 100000;
    $("k").value = 10; $("gather-rays").value = 0; $("spp").value = 1;
  } else if (integ === "photon") {
    $("photons").value = 200000; $("caustic-photons").value = 200000;
    $("k").value = 50; $("gather-rays").value = 8; $("spp").value = 4;
  }
  updateEstimate();
}

function num(id) {
  const v = $(id).value.trim();
  return v === "" ? undefined : Number(v);
}

/// The request body the form describes.
function formBody() {
  const integ = $("integrator").value;
  const params = { integrator: integ, spp: num("spp"), width: num("width"), height: num("height") };
  const exposure = num("exposure");
  if (exposure) params.exposure = exposure;
  if (integ !== "raytrace") {
    Object.assign(params, {
      photons: num("photons"), caustic_photons: num("caustic-photons"), k: num("k"),
      gather_rays: num("gather-rays"),
    });
    const effects = {};
    if (!$("fx-direct").checked) effects.direct_light = false;
    if (!$("fx-caustics").checked) effects.caustics = false;
    if (!$("fx-indirect").checked) effects.diffuse_interreflection = false;
    if (Object.keys(effects).length) params.effects = effects;
  }
  if (integ === "ppm") params.iterations = num("iterations");
  for (const k of Object.keys(params)) if (params[k] === undefined) delete params[k];
  const body = { params, public: $("public").checked };
  if (customScene()) {
    let scene;
    try {
      scene = JSON.parse($("scene-json").value);
    } catch (e) {
      throw new ApiError(400, { error: `not valid JSON: ${e.message}`, path: "scene" });
    }
    body.scene = scene;
  } else {
    body.scene_name = $("scene-name").value;
  }
  return body;
}

/// Seconds a job should take on the 2-core reference machine (README: "Time estimate"),
/// fitted to CLI renders of the Cornell box: photon tracing and map building at 1.7M photons/s;
/// per camera sample 0.35 us (raytrace), 0.7 us per camera or gather ray (photon), 0.9 us
/// (ppm, per pass); photon's irradiance precompute 25 ns per global photon and unit of k.
function estimateSeconds(p) {
  const pixels = (p.width || 384) * (p.height || 384);
  const integ = p.integrator || "photon";
  const samples = pixels * (p.spp || 1);
  if (integ === "raytrace") return 0.05 + samples * 0.35e-6;
  const photons = (p.photons || 0) + (p.caustic_photons || 0);
  if (integ === "ppm") return 0.05 + (p.iterations || 16) * (photons / 1.7e6 + samples * 0.9e-6);
  const gather = p.gather_rays == null ? 8 : p.gather_rays;
  return 0.05 + photons / 1.7e6 + samples * (1 + gather) * 0.7e-6 + (p.photons || 0) * (p.k || 50) * 25e-9;
}

/// Finished jobs' measured time over the model's estimate: the model scaled to this server.
function measuredScale() {
  const ratios = state.jobs
    .filter((j) => j.status === "done" && j.stats && j.stats.times && j.stats.times.total > 0.2)
    .slice(0, 10)
    .map((j) => j.stats.times.total / estimateSeconds(Object.assign({}, j.stats.params, j.params)))
    .sort((a, b) => a - b);
  return ratios.length ? ratios[Math.floor(ratios.length / 2)] : null;
}

function updateEstimate() {
  let params;
  try {
    params = formBody().params;
  } catch (_) {
    $("estimate").textContent = "-";
    return;
  }
  const base = estimateSeconds(params);
  const scale = measuredScale();
  const est = scale ? base * scale : base;
  $("estimate").textContent = `about ${fmtSeconds(est)}`;
  $("estimate").dataset.seconds = est.toFixed(3);
  $("estimate-note").textContent = scale
    ? `(model x ${scale.toFixed(2)}, from your server's recent jobs)`
    : "(model of a 2-core machine)";
}

function clearErrors() {
  $("form-error").textContent = "";
  for (const el of document.querySelectorAll("#submit-form [aria-invalid]")) {
    el.removeAttribute("aria-invalid");
  }
  for (const el of document.querySelectorAll("#submit-form .field .error, #effects .error")) {
    el.textContent = "";
  }
}

/// Show an API error next to the field its path names (the longest `data-path` prefix).
function showError(err) {
  const path = err.path || "";
  let best = null;
  for (const el of document.querySelectorAll("#submit-form [data-path]")) {
    const p = el.dataset.path;
    const matches = path === p || path.startsWith(`${p}.`) || path.startsWith(`${p}[`);
    if (matches && (!best || p.length > best.dataset.path.length)) best = el;
  }
  // A scene error while a built-in scene is chosen belongs to the scene select.
  if (best && best.id === "scene-json" && !customScene()) best = $("scene-name");
  const slot = best && $(`${best.id}-error`);
  const text = path ? `${path}: ${err.message}` : err.message;
  if (slot && !best.closest("[hidden]")) {
    slot.textContent = text;
    best.setAttribute("aria-invalid", "true");
    best.focus();
  } else {
    $("form-error").textContent = text;
  }
}

async function submitForm(ev) {
  ev.preventDefault();
  clearErrors();
  const button = $("submit");
  button.disabled = true;
  try {
    const body = formBody();
    const res = await apiJson("/api/jobs", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify(body),
    });
    location.hash = `#/job/${res.id}`;
  } catch (e) {
    if (e instanceof ApiError) showError(e);
    else $("form-error").textContent = `Could not submit: ${e.message}`;
  } finally {
    button.disabled = false;
  }
}

// ---------------------------------------------------------------- job page

async function openJob(id, signal) {
  showView("job");
  $("job-title").textContent = `Job ${id}`;
  document.title = `photonbox: job ${id}`;
  $("job-error").textContent = "";
  $("job-summary").textContent = "";
  $("job-stats").replaceChildren();
  $("job-progress").value = 0;
  $("job-progress-text").textContent = "";
  const img = $("job-image");
  img.hidden = true;
  img.removeAttribute("src");
  $("job-noimage").hidden = false;
  let job;
  try {
    job = await apiJson(`/api/jobs/${id}`, { signal });
  } catch (e) {
    if (signal.aborted) return;
    $("job-error").textContent = e.status === 404 ? `There is no job ${id} you may see.` : e.message;
    return;
  }
  await refreshGallery(); // for the "compare with" choice
  showJob(job);
  fillCompareWith(job);
  await showJobImage(job, signal);
  // Follow the job live until it ends; reconnect if the stream drops early.
  while (!signal.aborted && !isFinal(job.status)) {
    try {
      await followEvents(id, (name, snap) => {
        if (!snap) return;
        Object.assign(job, snap);
        showProgress(job);
        if (name === "preview") showJobImage(job, signal);
      }, signal);
    } catch (_) {
      if (signal.aborted) return;
    }
    if (signal.aborted) return;
    try {
      job = await apiJson(`/api/jobs/${id}`, { signal });
    } catch (_) {
      return;
    }
    showJob(job);
    if (isFinal(job.status)) await showJobImage(job, signal);
    else await new Promise((r) => setTimeout(r, 1000));
  }
}

function isFinal(status) {
  return status === "done" || status === "failed" || status === "cancelled";
}

async function showJobImage(job, signal) {
  const img = $("job-image");
  const ok = await loadImage(img, `/api/jobs/${job.id}/image.png`, signal).catch(() => false);
  if (!ok) return;
  img.alt = `Render of ${sceneOf(job)} (job ${job.id}, ${integratorOf(job)}${isFinal(job.status) ? "" : ", latest preview"})`;
  $("job-noimage").hidden = true;
  $("download-png").disabled = false;
  $("download-exr").disabled = false;
  applyZoom(img, $("job-zoom").value);
  img.dataset.loads = String(Number(img.dataset.loads || 0) + 1);
}

function applyZoom(img, zoom) {
  if (zoom === "fit") {
    img.style.width = "";
    img.classList.add("fit");
  } else {
    img.classList.remove("fit");
    if (img.naturalWidth) img.style.width = `${img.naturalWidth * Number(zoom)}px`;
  }
  img.classList.toggle("pixelated", zoom !== "fit" && Number(zoom) > 1);
}

function showJob(job) {
  state.currentJob = job;
  $("job-title").textContent = `Job ${job.id}: ${sceneOf(job)}`;
  $("job-summary").textContent =
    `${integratorOf(job)} · ${keyParams(job)} · ${job.mine ? "yours" : `by ${job.owner}`} · ` +
    `${job.public ? "public" : "private"} · submitted ${fmtTime(job.created)}`;
  $("job-error").textContent = job.error ? `Error: ${job.error}` : "";
  const canCancel = job.mine || (state.me && state.me.admin);
  const cancel = $("job-cancel");
  cancel.hidden = !canCancel;
  cancel.textContent = isFinal(job.status) ? "Delete" : "Cancel";
  const hasImage = !$("job-image").hidden;
  $("download-png").disabled = !hasImage;
  $("download-exr").disabled = !hasImage;
  showProgress(job);
  showStats(job);
}

function showProgress(job) {
  const bar = $("job-progress");
  bar.value = job.progress || 0;
  bar.dataset.status = job.status;
  let text;
  if (job.status === "running") {
    const phase = PHASES[job.phase] || job.phase || "starting";
    const eta = job.eta_seconds != null ? `, about ${fmtSeconds(job.eta_seconds)} left` : "";
    text = `${Math.round((job.progress || 0) * 100)}%: ${phase}${eta}`;
  } else if (job.status === "queued") {
    text = job.queue_position != null ? `queued, position ${job.queue_position + 1}` : "queued";
  } else {
    text = job.status;
  }
  $("job-progress-text").textContent = text;
  $("job-progress-text").dataset.status = job.status;
  if (state.currentJob && state.currentJob.id === job.id) {
    $("job-cancel").textContent = isFinal(job.status) ? "Delete" : "Cancel";
  }
}

function table(caption, rows, head) {
  const t = document.createElement("table");
  const c = document.createElement("caption");
  c.textContent = caption;
  t.appendChild(c);
  if (head) {
    const tr = document.createElement("tr");
    for (const h of head) {
      const th = document.createElement("th");
      th.scope = "col";
      th.textContent = h;
      tr.appendChild(th);
    }
    t.appendChild(tr);
  }
  for (const row of rows) {
    const tr = document.createElement("tr");
    row.forEach((cell, i) => {
      const td = document.createElement(i === 0 ? "th" : "td");
      if (i === 0) td.scope = "row";
      td.textContent = cell;
      tr.appendChild(td);
    });
    t.appendChild(tr);
  }
  // A wide table scrolls inside its box, not the page (phones).
  const wrap = document.createElement("div");
  wrap.className = "table-wrap";
  wrap.appendChild(t);
  return wrap;
}

function showStats(job) {
  const box = $("job-stats");
  box.replaceChildren();
  const rows = [
    ["status", job.status],
    ["submitted", fmtTime(job.created)],
    ["started", fmtTime(job.started)],
    ["finished", fmtTime(job.finished)],
    ["wall time", fmtSeconds(duration(job))],
  ];
  box.appendChild(table("Job", rows));
  const s = job.stats;
  if (!s || typeof s !== "object") {
    const p = document.createElement("p");
    p.className = "hint";
    p.textContent = "Statistics appear when the render is done.";
    box.appendChild(p);
    return;
  }
  if (s.times) {
    const t = s.times;
    box.appendChild(table("Time per phase", [
      ["photon tracing", fmtSeconds(t.photon_trace)],
      ["building maps", fmtSeconds(t.build_maps)],
      ["irradiance precompute", fmtSeconds(t.precompute)],
      ["camera pass", fmtSeconds(t.render)],
      ["total", fmtSeconds(t.total)],
    ]));
  }
  if (s.photons) {
    const p = s.photons;
    const cache = s.cache && s.cache.photon_maps;
    box.appendChild(table("Photons", [
      ["global emitted / stored", `${fmtCount(p.global_emitted)} / ${fmtCount(p.global_stored)}`],
      ["caustic emitted / stored", `${fmtCount(p.caustic_emitted)} / ${fmtCount(p.caustic_stored)}`],
      ["traced by this job", fmtCount(p.traced_by_this_job)],
      ["photon-map cache", cache === "hit" ? "hit (maps reused)" : cache || "-"],
      ["map memory", p.map_bytes != null ? `${(p.map_bytes / 1048576).toFixed(1)} MiB` : "-"],
    ]));
  }
  if (s.effects) {
    const rows = Object.entries(s.effects).map(([name, e]) => [
      name.replace(/_/g, " "), e.simulated ? "yes" : "no", e.how || "", e.reason || "",
    ]);
    box.appendChild(table("Effects simulated, and why", rows, ["effect", "simulated", "how", "reason"]));
  }
  if (s.ppm) {
    box.appendChild(table("Progressive passes", [
      ["passes", String(s.ppm.passes)],
      ["alpha", String(s.ppm.alpha)],
      ["initial radius (global / caustic)",
        `${(+s.ppm.radius_initial_global).toPrecision(3)} / ${(+s.ppm.radius_initial_caustic).toPrecision(3)} (${s.ppm.radius_source})`],
      ["stopped by", typeof s.ppm.stopped_by === "string" ? s.ppm.stopped_by : JSON.stringify(s.ppm.stopped_by)],
    ]));
    const chart = convergence(s.ppm);
    if (chart) box.appendChild(chart);
  }
}

/// A log-log line chart of `series` ([{ name, points: [[x, y]...] }]) as an SVG figure.
function logChart(title, xLabel, series) {
  const W = 360, H = 220, L = 48, R = 10, T = 10, B = 34;
  series = series.filter((s) => s.points.some(([x, y]) => x > 0 && y > 0));
  const all = series.flatMap((s) => s.points).filter(([x, y]) => x > 0 && y > 0);
  const fig = document.createElement("figure");
  fig.className = "chart";
  const cap = document.createElement("figcaption");
  cap.textContent = title;
  if (all.length < 2) return null;
  const lx = all.map(([x]) => Math.log10(x)), ly = all.map(([, y]) => Math.log10(y));
  const [x0, x1] = [Math.min(...lx), Math.max(...lx) || 1];
  let [y0, y1] = [Math.min(...ly), Math.max(...ly)];
  if (y1 - y0 < 1e-9) { y0 -= 0.5; y1 += 0.5; }
  const px = (x) => L + ((Math.log10(x) - x0) / (x1 - x0 || 1)) * (W - L - R);
  const py = (y) => T + (1 - (Math.log10(y) - y0) / (y1 - y0)) * (H - T - B);
  const NS = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(NS, "svg");
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", `${title} (log-log), ${series.map((s) => s.name).join(", ")}`);
  const add = (tag, attrs, text) => {
    const el = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
    if (text != null) el.textContent = text;
    svg.appendChild(el);
    return el;
  };
  add("rect", { x: L, y: T, width: W - L - R, height: H - T - B, class: "plot" });
  const fmt = (v) => (v >= 0.01 && v < 1000 ? +v.toPrecision(2) : v.toExponential(0));
  add("text", { x: L, y: H - 18, class: "tick" }, fmt(10 ** x0));
  add("text", { x: W - R, y: H - 18, class: "tick end" }, fmt(10 ** x1));
  add("text", { x: L - 4, y: T + 10, class: "tick end" }, fmt(10 ** y1));
  add("text", { x: L - 4, y: H - B, class: "tick end" }, fmt(10 ** y0));
  add("text", { x: (L + W - R) / 2, y: H - 4, class: "tick mid" }, xLabel);
  series.forEach((s, i) => {
    const pts = s.points.filter(([x, y]) => x > 0 && y > 0);
    add("polyline", {
      class: `line line${i}`, "data-series": s.name,
      points: pts.map(([x, y]) => `${px(x).toFixed(1)},${py(y).toFixed(1)}`).join(" "),
    });
    add("text", { x: W - R - 4, y: T + 14 + 14 * i, class: `tick end label${i}` }, s.name);
  });
  fig.append(svg, cap);
  return fig;
}

/// How a progressive render converged: the estimate radius shrinking pass by pass, the time
/// per pass, and the error per pass when the render had a reference.
function convergence(ppm) {
  const h = (ppm && ppm.history) || [];
  if (h.length < 2) return null;
  const series = [
    { name: "global radius", points: h.map((p) => [p.pass, p.radius_global]) },
    { name: "caustic radius", points: h.map((p) => [p.pass, p.radius_caustic]) },
  ];
  if (h.some((p) => p.error)) {
    series.push({ name: "relmse", points: h.filter((p) => p.error).map((p) => [p.pass, p.error.relmse]) });
  }
  const box = document.createElement("div");
  box.className = "charts";
  const a = logChart("Estimate radius per pass (scene units)", "pass", series);
  const b = logChart("Time: seconds elapsed after each pass", "pass",
    [{ name: "elapsed", points: h.map((p) => [p.pass, p.elapsed]) }]);
  for (const f of [a, b]) if (f) box.appendChild(f);
  return box;
}

function fillCompareWith(job) {
  const sel = $("job-compare-with");
  sel.replaceChildren();
  const others = state.jobs.filter((j) => j.id !== job.id && j.status !== "queued");
  for (const j of others) {
    const o = document.createElement("option");
    o.value = j.id;
    o.textContent = `#${j.id} ${sceneOf(j)} (${integratorOf(j)})`;
    sel.appendChild(o);
  }
  for (const el of [sel, sel.labels[0], $("job-compare")]) el.hidden = others.length === 0;
}

async function download(ext) {
  const job = state.currentJob;
  const r = await api(`/api/jobs/${job.id}/image.${ext}`);
  if (!r.ok) {
    $("job-error").textContent = `No ${ext.toUpperCase()} yet.`;
    return;
  }
  const url = URL.createObjectURL(await r.blob());
  const a = document.createElement("a");
  a.href = url;
  a.download = `photonbox-job-${job.id}.${ext}`;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

async function cancelJob() {
  const job = state.currentJob;
  if (isFinal(job.status) && !confirm(`Delete job ${job.id} and its images?`)) return;
  try {
    const res = await apiJson(`/api/jobs/${job.id}`, { method: "DELETE" });
    if (!res) {
      location.hash = "#/";
      return;
    }
    Object.assign(job, { status: res.status });
    showProgress(job);
  } catch (e) {
    $("job-error").textContent = e.message;
  }
}

// ---------------------------------------------------------------- compare

async function openCompare(a, b, signal) {
  showView("compare");
  document.title = "photonbox: compare";
  await refreshGallery();
  const withImages = state.jobs.filter((j) => j.status !== "queued");
  for (const id of ["compare-a", "compare-b"]) {
    const sel = $(id);
    sel.replaceChildren();
    for (const j of withImages) {
      const o = document.createElement("option");
      o.value = j.id;
      o.textContent = `#${j.id} ${sceneOf(j)} (${integratorOf(j)}, ${keyParams(j)})`;
      sel.appendChild(o);
    }
  }
  a = a || (withImages[1] && withImages[1].id);
  b = b || (withImages[0] && withImages[0].id);
  if (a) $("compare-a").value = a;
  if (b) $("compare-b").value = b;
  const sides = [["a", a], ["b", b]];
  for (const [side, id] of sides) {
    const job = state.jobs.find((j) => j.id === id);
    const img = $(`compare-img-${side}`);
    img.alt = job ? `${side === "a" ? "Left" : "Right"}: render of ${sceneOf(job)} (job ${id}, ${integratorOf(job)})` : "";
    $(`compare-caption-${side}`).textContent = job
      ? `${side === "a" ? "Left" : "Right"}: #${id} ${sceneOf(job)}, ${integratorOf(job)}, ${keyParams(job)}` +
        (job.stats && job.stats.times ? `, ${fmtSeconds(job.stats.times.total)}` : "")
      : "";
    if (id) await loadImage(img, `/api/jobs/${id}/image.png`, signal).catch(() => false);
  }
  applyCompareZoom();
  applySplit();
}

function applySplit() {
  const x = Number($("compare-split").value);
  $("compare-img-a").style.clipPath = `inset(0 ${100 - x}% 0 0)`;
  $("compare-line").style.left = `${x}%`;
  $("compare-split").setAttribute("aria-valuetext", `${x}% left image`);
}

function applyCompareZoom() {
  const zoom = $("compare-zoom").value;
  const a = $("compare-img-a"), b = $("compare-img-b");
  const stack = $("compare-stack");
  const w = a.naturalWidth || b.naturalWidth;
  stack.classList.toggle("fit", zoom === "fit");
  stack.style.width = zoom === "fit" || !w ? "" : `${w * Number(zoom)}px`;
  for (const img of [a, b]) img.classList.toggle("pixelated", zoom !== "fit" && Number(zoom) > 1);
}

// ---------------------------------------------------------------- wiring

function init() {
  takeTokenFromUrl();
  $("signin-form").addEventListener("submit", (ev) => {
    ev.preventDefault();
    const t = $("signin-token").value.trim();
    if (!t) return;
    localStorage.setItem(TOKEN_KEY, t);
    $("signin-token").value = "";
    signIn();
  });
  $("sign-out").addEventListener("click", () => signOut("Signed out."));
  $("submit-form").addEventListener("submit", submitForm);
  $("submit-form").addEventListener("input", () => {
    // Edited by hand: no preset describes the settings any more.
    for (const b of document.querySelectorAll("[data-preset]")) b.removeAttribute("aria-pressed");
    updateEstimate();
  });
  $("scene-name").addEventListener("change", onSceneChange);
  $("integrator").addEventListener("change", onIntegratorChange);
  for (const r of document.querySelectorAll("input[name=scene-source]")) {
    r.addEventListener("change", () => {
      $("builtin-scene").hidden = customScene();
      $("custom-scene").hidden = !customScene();
      updateEstimate();
    });
  }
  $("scene-file").addEventListener("change", async () => {
    const f = $("scene-file").files[0];
    if (f) {
      $("scene-json").value = await f.text();
      updateEstimate();
    }
  });
  for (const b of document.querySelectorAll("[data-preset]")) {
    b.addEventListener("click", () => applyPreset(b.dataset.preset));
  }
  $("job-zoom").addEventListener("change", () => applyZoom($("job-image"), $("job-zoom").value));
  $("download-png").addEventListener("click", () => download("png"));
  $("download-exr").addEventListener("click", () => download("exr"));
  $("job-cancel").addEventListener("click", cancelJob);
  $("job-compare").addEventListener("click", () => {
    location.hash = `#/compare/${state.currentJob.id}/${$("job-compare-with").value}`;
  });
  const recompare = () => { location.hash = `#/compare/${$("compare-a").value}/${$("compare-b").value}`; };
  $("compare-a").addEventListener("change", recompare);
  $("compare-b").addEventListener("change", recompare);
  $("compare-split").addEventListener("input", applySplit);
  $("compare-zoom").addEventListener("change", applyCompareZoom);
  window.addEventListener("hashchange", route);
  onIntegratorChange();
  signIn();
}

init();
