// gelgrip dashboard: follows /api/events (SSE), shows each sensor's MJPEG, depth and
// contact images, plots the deformation signals, and sends commands to the grasp API.
"use strict";

const $ = (id) => document.getElementById(id);
const WINDOW_S = 30;
const history = []; // [t_s, [deformation per sensor]]
let built = false;
let state = null;

// Off loopback the server wants its token; the login page sets a session cookie that
// every request here (and the streams) then carries.
async function command(path, body) {
  const headers = { "Content-Type": "application/json" };
  $("result").textContent = path + " …";
  try {
    const r = await fetch(path, { method: "POST", headers, body: JSON.stringify(body || {}) });
    if (r.status === 401) { window.location.href = "/login"; return null; }
    const text = await r.text();
    $("result").textContent = path + " → " + r.status + " " + text;
    $("result").dataset.status = String(r.status);
    return r.status === 202 ? JSON.parse(text) : null;
  } catch (e) {
    $("result").textContent = path + " failed: " + e;
    return null;
  }
}

// Grasps are goals: the server answers at once with an id, and the event stream carries
// the goal's progress (phase and force per finger) and its end.
let graspId = null;
$("grasp").onclick = async () => {
  const force = $("auto-force").checked ? "auto" : parseFloat($("force").value);
  const goal = await command("/api/grasps", { target_force_n: force });
  if (goal) graspId = goal.id;
};

function showGrasp(g) {
  if (g.id !== graspId) return;
  if (g.state === "running") {
    const fingers = g.fingers.map((f) => `${f.id} ${f.phase} ${fmt(f.force_n)} N`).join(" · ");
    $("result").textContent = `grasp ${g.id} running · ${fingers}`;
    $("result").dataset.status = "running";
  } else {
    const outcome = g.result ? JSON.stringify(g.result) : g.error || "ended";
    $("result").textContent = `grasp ${g.id} → done ${outcome}`;
    $("result").dataset.status = "done";
  }
}
$("release").onclick = () => command("/api/release");
$("stop").onclick = () => command("/api/stop");
$("estop").onclick = () => command("/api/estop");
$("task").onclick = () => command("/api/task", { name: $("task-name").value });
$("scene").onclick = () => command("/api/sim/scene", { name: $("scene-name").value });
$("fault").onclick = () => command("/api/sim/fault", {
  sensor: $("fault-sensor").value, capture_delay_us: parseInt($("fault-delay").value, 10) || 0,
  capture_jitter_us: parseInt($("fault-jitter").value, 10) || 0,
  clock_drift_ppm: parseFloat($("fault-drift").value) || 0,
});
// Every non-zero fault of one sensor, e.g. "f1.tip +20000 µs, jitter 500 µs, drift -100 ppm".
function faultText(f) {
  const x = f.faults;
  const parts = [
    x.capture_delay_us && `+${x.capture_delay_us} µs`,
    x.capture_jitter_us && `jitter ${x.capture_jitter_us} µs`,
    x.clock_drift_ppm && `drift ${x.clock_drift_ppm} ppm`,
    x.delivery_delay_us && `delivery +${x.delivery_delay_us} µs`,
    x.drop_rate && `drop ${x.drop_rate}`,
    x.corrupt_rate && `corrupt ${x.corrupt_rate}`,
  ].filter(Boolean);
  return `${f.sensor} ${parts.join(", ")}`;
}
$("fault-clear").onclick = () => command("/api/sim/fault", { sensor: $("fault-sensor").value });

// Fill a <select> with `names` once (keeping the user's choice when it is still there).
function options(id, names, selected) {
  const el = $(id);
  const key = names.join("\n");
  if (el.dataset.key === key) return;
  const keep = el.value || selected;
  el.innerHTML = names.map((n) => `<option>${n}</option>`).join("");
  if (names.includes(keep)) el.value = keep;
  el.dataset.key = key;
}

function build(s) {
  const hand = $("hand");
  hand.innerHTML = "";
  for (const sensor of s.sensors) {
    const id = sensor.id;
    const div = document.createElement("div");
    div.className = "sensor";
    div.id = "sensor-" + id;
    div.innerHTML =
      `<h3>${id}</h3><div class="views">` +
      `<a href="/api/sensors/${encodeURIComponent(id)}/stream.mjpg" title="MJPEG stream" class="camera-view"><img alt="${id} camera" class="camera">` +
      `<svg class="shear" viewBox="-1 -0.75 2 1.5" aria-label="${id} shear"><line x1="0" y1="0" x2="0" y2="0"></line><circle r="0.04"></circle></svg></a>` +
      `<img alt="${id} depth" class="depth">` +
      `<img alt="${id} contact" class="contact"></div>` +
      `<div class="values"></div>`;
    hand.appendChild(div);
  }
  built = true;
  for (const sensor of s.sensors) follow(sensor.id);
}

// Each camera view loads the newest frame, then the next one once it has arrived (at most
// 15 fps): one short request at a time per sensor, instead of one long MJPEG connection
// each (browsers allow six HTTP/1.1 connections per host).
const FRAME_PERIOD_MS = 66;
function follow(id) {
  const img = document.querySelector(`[id="sensor-${id}"] .camera`);
  if (!img) return;
  const next = () => setTimeout(() => {
    img.src = `/api/sensors/${encodeURIComponent(id)}/frame.jpg?t=${Date.now()}`;
  }, FRAME_PERIOD_MS);
  img.onload = next;
  img.onerror = () => setTimeout(next, 500);
  next();
}

function refreshImages() {
  if (!state) return;
  const stamp = Date.now();
  for (const sensor of state.sensors) {
    const div = $("sensor-" + sensor.id);
    if (!div) continue;
    const id = encodeURIComponent(sensor.id);
    div.querySelector(".depth").src = `/api/sensors/${id}/depth.png?t=${stamp}`;
    div.querySelector(".contact").src = `/api/sensors/${id}/contact.png?t=${stamp}`;
  }
}
setInterval(refreshImages, 500);

const fmt = (v, d = 2) => (v === null || v === undefined ? "-" : Number(v).toFixed(d));

// The shear arrow's length at the view's edge, mm (the gel's dots move a few tenths of a
// millimetre before the contact slides).
const SHEAR_FULL_MM = 0.5;

// A sensor's shear as an arrow from the view's centre (x right, y down, as the image's
// axes), coloured by its slip state; hidden while its slip is unknown (a plain gel, or no
// dots under the contact).
function showShear(div, slip) {
  const svg = div.querySelector("svg.shear");
  svg.dataset.state = slip ? slip.state : "unknown";
  const line = svg.querySelector("line");
  const [x, y] = slip ? slip.shear_mm.map((v) => Math.max(-1, Math.min(1, v / SHEAR_FULL_MM))) : [0, 0];
  line.setAttribute("x2", String(x));
  line.setAttribute("y2", String(y * 0.75));
}

// One sensor's slip for its values line.
const slipText = (slip) => (slip
  ? ` · slip ${slip.state} (stick ${fmt(slip.stick_ratio)}, shear ${fmt(Math.hypot(...slip.shear_mm), 3)} mm)`
  : " · slip unknown");

function render(s) {
  state = s;
  if (!built || $("hand").children.length !== s.sensors.length) build(s);
  $("run").textContent = `${s.transport} · t ${fmt(s.t_s, 1)} s · ${s.sensors.length} sensors`;
  $("sync").textContent =
    `sets ${s.sync.sets} · ${fmt(s.sync.set_rate_hz, 1)} Hz · spread p99 ${s.sync.spread_us_p99 ?? "-"} µs · loop p99 ${fmt(s.sync.loop_latency_ms_p99)} ms` +
    (s.sync.excluded_sensors.length
      ? " · excluded: " + s.sync.excluded_sensors.map((e) => `${e.sensor} (${e.reason} since ${fmt(e.since_s, 1)} s)`).join(", ")
      : "");
  $("calibration").textContent = s.calibration;
  for (const sensor of s.sensors) {
    const div = $("sensor-" + sensor.id);
    if (!div) continue;
    div.classList.toggle("touch", sensor.in_contact);
    div.classList.toggle("missing", !sensor.ok && !sensor.excluded);
    div.classList.toggle("excluded", sensor.excluded);
    div.querySelector(".values").textContent = sensor.excluded
      ? "excluded from the sets: out of sync (its finger carries on with its other sensors, or holds)"
      : `${fmt(sensor.force_n)} N · ${fmt(sensor.area_mm2, 1)} mm² · ${fmt(sensor.max_depth_mm, 3)} mm · ${fmt(sensor.deformation_mm3, 1)} mm³ · age ${fmt(sensor.frame_age_ms, 1)} ms` +
        (sensor.in_contact ? slipText(sensor.slip) : "");
    showShear(div, sensor.slip);
  }
  const maxForce = Math.max(1, ...s.fingers.map((f) => Math.max(f.force_n, f.target_force_n)));
  $("fingers").innerHTML =
    "<tr><th>finger</th><th>phase</th><th>force N</th><th>target N</th><th>slip</th><th></th></tr>" +
    s.fingers.map((f) =>
      `<tr id="finger-${f.id}"><td>${f.id}</td><td class="phase">${f.phase}</td><td>${fmt(f.force_n)}</td><td>${fmt(f.target_force_n)}</td>` +
      `<td class="slip" data-state="${f.slip_state ?? "unknown"}">${f.slip_state ?? "unknown"}</td>` +
      `<td><span class="bar" style="width:${(100 * f.force_n) / maxForce}px"></span>` +
      `<span class="bar target" style="width:${(100 * Math.max(0, f.target_force_n - f.force_n)) / maxForce}px"></span></td></tr>`
    ).join("");
  $("grasp-state").textContent = `slip ${s.slip_state ?? "unknown"}` +
    (s.settled_force_n === null || s.settled_force_n === undefined ? "" : ` · settled ${fmt(s.settled_force_n)} N per finger`);
  $("grasp-state").dataset.state = s.slip_state ?? "unknown";
  $("servos").innerHTML =
    "<tr><th>finger</th><th>position °</th><th>current mA</th><th>temp °C</th><th>errors</th></tr>" +
    s.servos.map((v) =>
      `<tr><td>${v.finger}</td><td>${fmt(v.position_deg, 1)}</td><td>${fmt(v.current_ma, 0)}</td><td>${fmt(v.temperature_c, 1)}</td><td>${v.errors.join(", ") || "none"}</td></tr>`
    ).join("");
  const total = Math.max(1, ...s.sync.spread_histogram_us.map((b) => b[1]));
  $("histogram").innerHTML = s.sync.spread_histogram_us
    .map((b) => `<div>≤ ${b[0]} µs <span class="bar" style="width:${(150 * b[1]) / total}px"></span> ${b[1]}</div>`)
    .join("") || "no sets yet";
  $("drops").innerHTML =
    "<tr><th>reason</th><th>frames</th><th>sets refused</th></tr>" +
    Object.keys(s.sync.drops).map((k) => `<tr><td>${k}</td><td>${s.sync.drops[k]}</td><td>${s.sync.sets_rejected[k]}</td></tr>`).join("");
  $("taskstate").textContent = !s.task ? "none"
    : s.task.running ? `${s.task.name}: ${s.task.stage}`
    : `${s.task.name}: ended in ${s.task.stage} (${s.task.outcome})`;
  options("task-name", s.tasks_available, "pick-and-release");
  $("task").disabled = !s.tasks_available.length || Boolean(s.task && s.task.running);
  $("sim").hidden = !s.sim;
  if (s.sim) {
    options("scene-name", s.sim.scenes, s.sim.scene);
    options("fault-sensor", s.sensors.map((x) => x.id), s.sensors.length ? s.sensors[0].id : "");
    $("faults").textContent = `scene ${s.sim.scene}; ` + (s.sim.faults.length
      ? "faults: " + s.sim.faults.map(faultText).join("; ")
      : "no faults injected");
  }
  const last = history.length ? history[history.length - 1][0] : -Infinity;
  if (s.t_s < last) history.length = 0; // a new run behind the same server
  if (s.t_s > last) history.push([s.t_s, s.sensors.map((x) => x.deformation_mm3)]);
  while (history.length && s.t_s - history[0][0] > WINDOW_S) history.shift();
  plot(s.sensors.map((x) => x.id));
}

const COLORS = ["#d62728", "#2ca02c", "#e6b800", "#1f77b4", "#ff7f0e", "#9467bd", "#17becf", "#8c564b"];

// The tick labels shown per axis element, so they are rebuilt only when they change.
const axisShown = {};

// Show `ticks` as `<span class="tick">` in the axis element `id`, each at `at(value)`, a
// fraction of the canvas's height (vertical) or width.
function axisLabels(id, ticks, vertical, at) {
  const key = ticks.map((t) => t.label + "@" + at(t.value).toFixed(4)).join("|");
  if (axisShown[id] === key) return;
  axisShown[id] = key;
  $(id).replaceChildren(...ticks.map((t) => {
    const span = document.createElement("span");
    span.className = "tick";
    span.textContent = t.label;
    span.style[vertical ? "top" : "left"] = (100 * at(t.value)).toFixed(2) + "%";
    return span;
  }));
}

function plot(ids) {
  const c = $("plot");
  const g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  if (history.length < 2) return;
  const t1 = history[history.length - 1][0];
  const t0 = t1 - WINDOW_S;
  let lo = 0;
  let hi = 0;
  for (const h of history) {
    for (const v of h[1]) {
      if (Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    }
  }
  // A floor of 0.001 mm³ gives a flat signal distinct labels; a 0.05 mm³ one fills the chart.
  hi = Math.max(lo + (hi - lo) * 1.1, lo + 0.001);
  const yTicks = gelgripAxis.axisTicks(lo, hi, "mm³", 5);
  const xTicks = gelgripAxis.axisTicks(-WINDOW_S, 0, "s", 7); // seconds before the newest
  const [left, right, top, bottom] = [6, c.width - 16, 20, c.height - 8];
  const x = (t) => left + ((t - t0) / WINDOW_S) * (right - left);
  const y = (v) => bottom - ((v - lo) / (hi - lo)) * (bottom - top);
  g.strokeStyle = "#ccc";
  g.beginPath();
  yTicks.forEach((t) => { g.moveTo(left, y(t.value)); g.lineTo(right, y(t.value)); });
  xTicks.forEach((t) => { g.moveTo(x(t1 + t.value), top); g.lineTo(x(t1 + t.value), bottom); });
  g.stroke();
  axisLabels("plot-y-axis", yTicks, true, (v) => y(v) / c.height);
  axisLabels("plot-x-axis", xTicks, false, (v) => x(t1 + v) / c.width);
  g.font = "11px sans-serif";
  ids.forEach((id, i) => {
    g.strokeStyle = COLORS[i % COLORS.length];
    g.beginPath();
    let gap = true; // a missing reading breaks the line rather than dropping it to zero
    history.forEach((h) => {
      const v = h[1][i];
      if (!Number.isFinite(v)) { gap = true; return; }
      if (gap) g.moveTo(x(h[0]), y(v)); else g.lineTo(x(h[0]), y(v));
      gap = false;
    });
    g.stroke();
    g.fillStyle = COLORS[i % COLORS.length];
    g.fillText(id, 45 + (i % 8) * 90, 12);
  });
}

function connect() {
  const events = new EventSource("/api/events");
  // The server's last 30 s of the signals come first, so the chart starts full.
  events.addEventListener("history", (e) => {
    const h = JSON.parse(e.data);
    history.length = 0;
    h.t_s.forEach((t, k) => history.push([t, h.deformation_mm3[k]]));
  });
  events.addEventListener("state", (e) => render(JSON.parse(e.data)));
  events.addEventListener("grasp", (e) => showGrasp(JSON.parse(e.data)));
  events.onerror = () => { $("run").textContent = "disconnected; retrying…"; };
}
connect();
