// The calibration view of `gelgrip calibrate collect`: polls GET /api/calibrate, reloads
// the difference image when a newer one exists, and sends Keep / Redo for the press
// waiting (its `attempt`), exactly as `Enter` / `r` on the terminal would.
"use strict";

const $ = (id) => document.getElementById(id);
let status = null;
let shownImage = -1;
let loading = false;

function phaseText(s) {
  switch (s.phase) {
    case "background": return "taking the background: leave the sensor untouched and press Enter in the terminal";
    case "pressing": return "waiting for a settled press";
    case "deciding": return `attempt ${s.attempt}: keep it or redo it?`;
    case "done": return "done: every press wanted is kept";
    default: return "the session has ended";
  }
}

function render(s) {
  status = s;
  $("sensor").textContent = `on ${s.sensor} · ${s.ball_mm} mm ball · ${s.mm_per_px} mm/px · into ${s.out}`;
  $("count").textContent = `${s.kept}/${s.wanted}`;
  $("phase").textContent = phaseText(s);
  $("message").textContent = s.message;
  const l = s.label;
  $("label").textContent = l
    ? `centre (${l.center_x_px.toFixed(1)}, ${l.center_y_px.toFixed(1)}) px · radius ${l.contact_radius_px.toFixed(1)} px · score ${l.score.toFixed(2)}`
    : "";
  $("rejection").textContent = s.rejection ? `not usable: ${s.rejection}` : "";
  const deciding = s.phase === "deciding" && s.attempt !== null;
  $("keep").disabled = !deciding;
  $("redo").disabled = !deciding;
  if (s.image > 0 && s.image !== shownImage && !loading) {
    loading = true;
    const img = $("difference");
    const n = s.image;
    img.onload = img.onerror = () => { loading = false; shownImage = n; };
    img.src = `/api/calibrate/difference.png?n=${n}`;
  }
}

async function poll() {
  try {
    const r = await fetch("/api/calibrate", { cache: "no-store" });
    if (r.status === 401) { location.href = "/login"; return; }
    if (r.ok) render(await r.json());
  } catch (e) {
    $("phase").textContent = "the collect session is gone (it ended, or the connection dropped)";
  }
  setTimeout(poll, 200);
}

async function decide(what) {
  if (!status || status.attempt === null) return;
  const attempt = status.attempt;
  $("keep").disabled = true;
  $("redo").disabled = true;
  try {
    const r = await fetch(`/api/calibrate/${what}`, {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ attempt }),
    });
    const body = await r.json();
    $("result").textContent = r.ok ? `attempt ${attempt}: ${body.decision}` : body.error;
    // Answered once the session acted on it: a kept press is on disk and counted.
    if (r.ok && body.status) render(body.status);
  } catch (e) {
    $("result").textContent = `${what}: ${e}`;
  }
}

$("keep").addEventListener("click", () => decide("keep"));
$("redo").addEventListener("click", () => decide("redo"));
poll();
