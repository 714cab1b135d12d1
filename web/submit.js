// The submit form: scene choice (built-in or JSON), settings and presets, the time estimate,
// and a server error shown next to the field its `path` names.

import { ApiError, apiJson } from "./api.js";
import { fmtSeconds, sceneOf } from "./format.js";
import { $, state } from "./state.js";

/// The form's fields that are spec parameters: element id -> field of `params`.
const SPEC_FIELDS = {
  photons: "photons", "caustic-photons": "caustic_photons", k: "k", "gather-rays": "gather_rays",
  spp: "spp", iterations: "iterations",
};

/// Presets, per integrator: the fields they set, over the integrator's defaults (`good` is
/// the defaults themselves, as the server's spec has them), and the scale of the scene's own
/// resolution. `passes` serves every integrator not named (auto and the bidirectional
/// family: a number of passes).
const PRESETS = {
  draft: {
    photon: { photons: 50000, caustic_photons: 50000, k: 30, gather_rays: 0, spp: 1 },
    ppm: { photons: 20000, caustic_photons: 20000, iterations: 8 },
    raytrace: { spp: 1 },
    passes: { iterations: 4 },
    scale: 0.5,
  },
  good: { photon: {}, ppm: { iterations: 32 }, raytrace: {}, passes: {}, scale: 1 },
  final: {
    photon: { photons: 1000000, caustic_photons: 1000000, k: 100, gather_rays: 16, spp: 16 },
    ppm: { photons: 200000, caustic_photons: 200000, iterations: 256 },
    raytrace: { spp: 16 },
    passes: { iterations: 256 },
    scale: 2,
  },
};

/// Fill the spec fields with `values` over the integrator's defaults.
function fillSpecFields(integ, values) {
  const defaults = (state.defaults && state.defaults[integ]) || {};
  for (const [id, field] of Object.entries(SPEC_FIELDS)) {
    const v = field in values ? values[field] : defaults[field];
    $(id).value = v == null ? "" : v;
  }
}

function applyPreset(name) {
  const preset = PRESETS[name];
  const integ = $("integrator").value;
  fillSpecFields(integ, preset[integ] || preset.passes);
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

export function fillScenes() {
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

/// The reference choice: finished jobs the user may see, newest first (`state.jobs`).
export function fillReferences() {
  const sel = $("reference-job");
  const prev = sel.value;
  const none = document.createElement("option");
  none.value = "";
  none.textContent = "none";
  const options = [none];
  for (const j of state.jobs.filter((j) => j.status === "done")) {
    const o = document.createElement("option");
    o.value = j.id;
    const p = (j.stats && j.stats.params) || {};
    o.textContent = `#${j.id} ${sceneOf(j)} (${p.integrator || "?"}, ${p.width}x${p.height})`;
    options.push(o);
  }
  sel.replaceChildren(...options);
  if (options.some((o) => o.value === prev)) sel.value = prev;
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

/// Whether the integrator reads a field of the spec: its defaults (the server's) have it.
function reads(integ, field) {
  const d = state.defaults && state.defaults[integ];
  return d ? field in d : field !== "iterations";
}

/// Short descriptions of the integrators the server offers (its defaults name them).
const INTEGRATORS = {
  photon: "photon (photon maps)", raytrace: "raytrace (direct light only)",
  ppm: "ppm (progressive photon mapping)", pt: "pt (path tracing)", lt: "lt (light tracing)",
  bdpt: "bdpt (bidirectional path tracing)", vcm: "vcm (vertex connection and merging)",
  auto: "auto (the scene's choice: pt, bdpt, vcm, or photon for a short time limit)",
};

/// The integrator choice: every integrator the server's spec has, its default first.
export function fillIntegrators() {
  const sel = $("integrator");
  const prev = sel.value;
  const names = state.defaults ? Object.keys(state.defaults) : ["photon"];
  sel.replaceChildren(...names.map((name) => {
    const o = document.createElement("option");
    o.value = name;
    o.textContent = INTEGRATORS[name] || name;
    return o;
  }));
  if (names.includes(prev)) sel.value = prev;
}

export function onIntegratorChange() {
  const integ = $("integrator").value;
  document.body.dataset.integrator = integ;
  for (const el of document.querySelectorAll("[data-field]")) {
    el.hidden = !reads(integ, el.dataset.field);
  }
  // The new integrator's defaults, as the server's spec has them.
  fillSpecFields(integ, {});
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
  for (const [id, field] of Object.entries(SPEC_FIELDS)) {
    if (field !== "spp" && reads(integ, field)) params[field] = num(id);
  }
  if (reads(integ, "effects")) {
    const effects = {};
    if (!$("fx-direct").checked) effects.direct_light = false;
    if (!$("fx-caustics").checked) effects.caustics = false;
    if (!$("fx-indirect").checked) effects.diffuse_interreflection = false;
    if (Object.keys(effects).length) params.effects = effects;
  }
  const reference = $("reference-job").value;
  if (reference) params.reference_job = Number(reference);
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
function estimateSeconds(params) {
  const integ = params.integrator || "photon";
  // What the form leaves empty, the server fills with its defaults.
  const p = Object.assign({}, (state.defaults && state.defaults[integ]) || {}, params);
  const pixels = (p.width || 384) * (p.height || 384);
  const samples = pixels * (p.spp || 1);
  if (integ === "raytrace") return 0.05 + samples * 0.35e-6;
  // The bidirectional family: a pass is a light and a camera subpath per sample (measured
  // on cornell_mirror_glass at 384x384, 16 passes).
  const perSample = { pt: 0.3e-6, lt: 0.35e-6, bdpt: 1.05e-6, vcm: 2.2e-6 }[integ];
  if (perSample) return 0.05 + (p.iterations || 1) * samples * perSample;
  const photons = (p.photons || 0) + (p.caustic_photons || 0);
  if (integ === "ppm") return 0.05 + (p.iterations || 1) * (photons / 1.7e6 + samples * 0.9e-6);
  return 0.05 + photons / 1.7e6 + samples * (1 + (p.gather_rays || 0)) * 0.7e-6
    + (p.photons || 0) * (p.k || 1) * 25e-9;
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

export function updateEstimate() {
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

export function initSubmit() {
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
}
