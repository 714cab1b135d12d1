// Comparing two renders: one image over the other, the left one clipped at a slider.

import { loadImage } from "./api.js";
import { fmtSeconds, integratorOf, keyParams, sceneOf } from "./format.js";
import { refreshGallery } from "./gallery.js";
import { $, showView, state } from "./state.js";

/// The view `#/compare/A/B`; without ids, the two newest jobs with an image.
export async function openCompare(a, b, signal) {
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

export function initCompare() {
  const recompare = () => { location.hash = `#/compare/${$("compare-a").value}/${$("compare-b").value}`; };
  $("compare-a").addEventListener("change", recompare);
  $("compare-b").addEventListener("change", recompare);
  $("compare-split").addEventListener("input", applySplit);
  $("compare-zoom").addEventListener("change", applyCompareZoom);
}
