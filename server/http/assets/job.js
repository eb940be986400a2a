// SPDX-License-Identifier: Apache-2.0
// The job page of ergd's dashboard (GET /jobs/ID): the latest preview at
// full size, a slider over the job's snapshots, plots over simulated time
// drawn from the job's progress events (inline SVG, no library), the event
// and steering log, and cancel and steer controls. Everything it loads
// comes from ergd itself, with the page's session cookie.
"use strict";

const jobId = document.body.dataset.job;
const api = "/api/jobs/" + encodeURIComponent(jobId);
const UNIT_M = Math.pow(2, -32);  // height of one exact sand unit (README, "Outputs")
let job = null;
let followLatest = true;

function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  return e;
}

function years(days) { return Number(days || 0) / 365.25; }

function fmtSeconds(s) {
  if (!(s >= 0)) return "--:--";
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor(s / 60) % 60, r = s % 60;
  const two = (x) => String(x).padStart(2, "0");
  return (h ? h + ":" + two(m) : m) + ":" + two(r);
}

// A line plot of points [[x, y], ...] as an SVG element.
function plot(id, title, xLabel, yLabel, points) {
  const W = 420, H = 220, L = 62, R = 12, T = 26, B = 40;
  const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  svg.setAttribute("width", W);
  svg.setAttribute("height", H);
  svg.setAttribute("id", id);
  svg.setAttribute("class", "plot");
  const add = (tag, attrs, text) => {
    const e = document.createElementNS("http://www.w3.org/2000/svg", tag);
    for (const k in attrs) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    svg.appendChild(e);
    return e;
  };
  add("text", {x: L, y: 16, class: "title"}, title);
  add("text", {x: (L + W - R) / 2, y: H - 6, "text-anchor": "middle"}, xLabel);
  add("text", {x: 12, y: (T + H - B) / 2, "text-anchor": "middle",
               transform: `rotate(-90 12 ${(T + H - B) / 2})`}, yLabel);
  add("rect", {x: L, y: T, width: W - L - R, height: H - T - B, class: "frame"});
  if (points.length === 0) {
    add("text", {x: (L + W - R) / 2, y: (T + H - B) / 2, "text-anchor": "middle"}, "no data yet");
    return svg;
  }
  let x0 = Math.min(...points.map(p => p[0])), x1 = Math.max(...points.map(p => p[0]));
  let y0 = Math.min(0, ...points.map(p => p[1])), y1 = Math.max(...points.map(p => p[1]));
  if (x1 <= x0) x1 = x0 + 1;
  if (y1 <= y0) y1 = y0 + 1;
  const sx = x => L + (x - x0) / (x1 - x0) * (W - L - R);
  const sy = y => H - B - (y - y0) / (y1 - y0) * (H - T - B);
  for (const [v, anchor, x, y] of [[x0, "start", L, H - B + 14], [x1, "end", W - R, H - B + 14]])
    add("text", {x, y, "text-anchor": anchor, class: "tick"}, v.toPrecision(3));
  for (const [v, y] of [[y0, H - B], [y1, T + 10]])
    add("text", {x: L - 4, y, "text-anchor": "end", class: "tick"}, v.toPrecision(3));
  add("polyline", {points: points.map(p => sx(p[0]).toFixed(1) + "," + sy(p[1]).toFixed(1)).join(" "),
                   class: "line"});
  if (points.length === 1) add("circle", {cx: sx(points[0][0]), cy: sy(points[0][1]), r: 3, class: "dot"});
  return svg;
}

function showSnapshot(step) {
  const img = document.getElementById("preview");
  img.dataset.loaded = "";
  img.src = api + "/preview.png?step=" + step;
  img.alt = "preview of step " + step;
  document.getElementById("preview-caption").textContent = "step " + step;
}

function renderJob() {
  const p = job.progress || {};
  const state = (job.state || "").replace("JOB_STATE_", "");
  document.getElementById("state").textContent = state;
  document.getElementById("state").className = state;
  const steps = Number(p.total_steps || 0), step = Number(p.step || 0);
  document.getElementById("summary").textContent =
      `step ${step} of ${steps} (${years(p.time_days).toFixed(1)} simulated years), ` +
      `${Number(p.steps_per_s || 0).toFixed(1)} steps/s` +
      (state === "RUNNING" ? `, ETA ${fmtSeconds(Number(p.eta_s))}` : "") +
      (job.failure_reason ? ` — ${job.failure_reason}` : "");
  const snaps = (job.snapshot_steps || []).map(Number);
  const slider = document.getElementById("slider");
  slider.max = Math.max(0, snaps.length - 1);
  slider.disabled = snaps.length < 2;
  slider.dataset.steps = snaps.join(",");
  if (snaps.length && followLatest) {
    slider.value = snaps.length - 1;
    const want = String(snaps[snaps.length - 1]);
    if (document.getElementById("preview-caption").textContent !== "step " + want) showSnapshot(want);
  }
  const live = state === "RUNNING" || state === "QUEUED";
  document.getElementById("cancel").disabled = !live;
  document.getElementById("steer").disabled = state !== "RUNNING";
}

function eventText(e) {
  if (e.progress) return null;  // plotted, not listed
  if (e.state_changed) return "state " + e.state_changed.replace("JOB_STATE_", "");
  if ("snapshot_step" in e) return "snapshot at step " + e.snapshot_step;
  if (e.steered) return "steered at step " + (e.steered.step || 0) + ": " + JSON.stringify(e.steered);
  if (e.message) return e.message;
  return JSON.stringify(e);
}

function renderEvents(events, relief) {
  const progress = events.filter(e => e.progress).map(e => e.progress);
  const cell = job.spec && job.spec.domain ? Number(job.spec.domain.cell_size_m || 1) : 1;
  const plots = document.getElementById("plots");
  plots.replaceChildren(
      plot("plot-rate", "progress rate", "simulated years", "steps / s",
           progress.map(p => [years(p.time_days), Number(p.steps_per_s || 0)])),
      plot("plot-relief", "relief (highest minus lowest ground)", "simulated years", "m",
           relief.map(r => [years(r.time_days), r.relief_m])),
      plot("plot-flux", "sand flux: sand in saltation", "simulated years", "m³",
           progress.filter(p => p.airborne_units_total)
               .map(p => [years(p.time_days), Number(p.airborne_units_total) * UNIT_M * cell * cell])));
  const table = document.getElementById("events");
  table.replaceChildren();
  const head = el("tr");
  head.append(el("th", {}, "time"), el("th", {}, "event"));
  table.append(head);
  for (const e of events) {
    const text = eventText(e);
    if (text === null) continue;
    const tr = el("tr", {class: e.steered ? "event steered" : "event"});
    tr.append(el("td", {}, new Date(Number(e.unix_ms)).toLocaleString()), el("td", {}, text));
    table.append(tr);
  }
}

async function getJson(url) {
  const r = await fetch(url, {credentials: "same-origin", cache: "no-store"});
  if (!r.ok) throw new Error(url + ": " + r.status + " " + (await r.text()));
  return r.json();
}

async function refresh() {
  try {
    job = await getJson(api);
    renderJob();
    const [events, relief] = await Promise.all([getJson(api + "/events"), getJson(api + "/relief")]);
    renderEvents(events, relief);
    document.body.dataset.ready = "1";
  } catch (err) {
    document.getElementById("control-result").textContent = String(err);
  }
  const state = job ? job.state : "";
  if (state === "RUNNING" || state === "QUEUED") setTimeout(refresh, 2000);
}

async function post(path, body) {
  const out = document.getElementById("control-result");
  const r = await fetch(api + path, {method: "POST", credentials: "same-origin", body,
                                     headers: {"Content-Type": "application/json"}});
  const text = await r.text();
  out.textContent = r.ok ? text : "refused (" + r.status + "): " + text;
  out.className = r.ok ? "ok" : "error";
  refresh();
}

document.getElementById("slider").addEventListener("input", (ev) => {
  const steps = ev.target.dataset.steps.split(",");
  followLatest = Number(ev.target.value) === steps.length - 1;
  showSnapshot(steps[Number(ev.target.value)]);
});
document.getElementById("preview").addEventListener("load", (ev) => { ev.target.dataset.loaded = "1"; });
document.getElementById("cancel").addEventListener("click", () => post("/cancel", ""));
document.getElementById("steer").addEventListener("click",
    () => post("/steer", document.getElementById("steer-event").value));
refresh();
