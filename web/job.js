// The job page (`#/job/ID`): the image and its previews, live progress from the SSE stream,
// statistics and charts, downloads, cancel or delete, and the way to a comparison.

import { api, apiJson, followEvents, loadImage } from "./api.js";
import { accuracy, convergence } from "./charts.js";
import {
  PHASES, duration, fmtCount, fmtSeconds, fmtTime, integratorOf, isFinal, keyParams, sceneOf,
} from "./format.js";
import { refreshGallery } from "./gallery.js";
import { $, showView, state } from "./state.js";

/// Show job `id` and follow it live until it ends or `signal` aborts (another view opens).
export async function openJob(id, signal) {
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
      ["auto's choice (pilot)", fmtSeconds(t.choose || 0)],
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
    const merges = s.ppm.radius_source !== "none";
    box.appendChild(table("Progressive passes", [
      ["passes", String(s.ppm.passes)],
      ...(merges ? [
        ["alpha", String(s.ppm.alpha)],
        ["initial radius (global / caustic)",
          `${(+s.ppm.radius_initial_global).toPrecision(3)} / ${(+s.ppm.radius_initial_caustic).toPrecision(3)} (${s.ppm.radius_source})`],
      ] : []),
      ["stopped by", typeof s.ppm.stopped_by === "string" ? s.ppm.stopped_by : JSON.stringify(s.ppm.stopped_by)],
    ]));
    const chart = convergence(s.ppm);
    if (chart) box.appendChild(chart);
  }
  if (s.error) {
    const e = s.error;
    const ref = job.params && job.params.reference_job;
    box.appendChild(table(`Error against the reference (job ${ref != null ? ref : "?"})`, [
      ["relmse", e.relmse.toPrecision(4)],
      ["block_err", e.block_err.toPrecision(4)],
      ["mean_ratio", e.mean_ratio.toPrecision(4)],
      ["rmse", e.rmse.toPrecision(4)],
    ]));
  }
  const errors = accuracy(s.ppm);
  if (errors) box.appendChild(errors);
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

export function initJob() {
  $("job-zoom").addEventListener("change", () => applyZoom($("job-image"), $("job-zoom").value));
  $("download-png").addEventListener("click", () => download("png"));
  $("download-exr").addEventListener("click", () => download("exr"));
  $("job-cancel").addEventListener("click", cancelJob);
  $("job-compare").addEventListener("click", () => {
    location.hash = `#/compare/${state.currentJob.id}/${$("job-compare-with").value}`;
  });
}
