"""The exported page's stylesheet and script: a 3D view of the run drawn on a 2D canvas.

The script (:data:`SCRIPT`, no library) reads the page's JSON data block (written by
:mod:`armlab.app.export.html`): per frame, the world positions of every chain's points
(base, each joint frame, tip; integers in units of ``scale`` m), the commanded pose
("ghost", or null) and the tip frame's axes. It projects them in perspective and draws
each link as a thick line and each joint as a disc, far ones first, over a ground grid
and the path each tip takes over the whole run. Dragging (mouse or one finger) orbits,
the wheel or two fingers zoom, a double click resets the view. The time slider and
play/pause (at a chosen speed) pick the frame; the charts' cursors
(:mod:`armlab.app.export.charts`) and the joint readout follow it. It writes only text
(``textContent``) and attributes of its own elements, and makes no request.
"""

from __future__ import annotations

#: The page's stylesheet (system fonts only: nothing is downloaded).
STYLE = """
:root { color-scheme: light; --ink: #1d2330; --muted: #5b6474; --line: #d9dde4; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
       color: var(--ink); background: #f6f7f9; }
main { max-width: 1120px; margin: 0 auto; padding: 16px; }
h1 { font-size: 22px; margin: 4px 0 2px; overflow-wrap: anywhere; }
h2 { font-size: 17px; margin: 2px 0 8px; }
.sub { color: var(--muted); margin: 0 0 12px; overflow-wrap: anywhere; }
section { background: #fff; border: 1px solid var(--line); border-radius: 8px;
          padding: 12px 14px; margin: 12px 0; }
table { border-collapse: collapse; width: 100%; }
th, td { text-align: left; padding: 4px 8px; border-bottom: 1px solid var(--line);
         vertical-align: top; overflow-wrap: anywhere; }
th { font-weight: 600; color: var(--muted); width: 30%; }
td.num { font-variant-numeric: tabular-nums; }
#joints th { width: 62%; overflow-wrap: break-word; }
#joints td { white-space: nowrap; }
.viewer { display: grid; grid-template-columns: minmax(0, 1fr) 260px; gap: 12px;
          align-items: start; }
@media (max-width: 760px) { .viewer { grid-template-columns: minmax(0, 1fr); } }
canvas#view { width: 100%; height: min(62vh, 520px); display: block; border-radius: 6px;
              background: #fbfbfd; border: 1px solid var(--line); touch-action: none;
              cursor: grab; }
.controls { display: flex; gap: 8px; align-items: center; margin-top: 8px; flex-wrap: wrap; }
.controls input[type=range] { flex: 1 1 240px; min-width: 160px; }
button, select { font: inherit; padding: 4px 12px; border-radius: 6px;
                 border: 1px solid #b9c0cc; background: #fff; }
#time-readout { font-variant-numeric: tabular-nums; min-width: 8em; }
.hint, .note { color: var(--muted); font-size: 13px; }
.charts { display: grid; grid-template-columns: repeat(auto-fit, minmax(420px, 1fr));
          gap: 10px; }
svg.chart { width: 100%; height: auto; background: #fff; }
svg.chart text { font: 11px system-ui, sans-serif; fill: var(--ink); }
svg.chart text.title { font-weight: 600; font-size: 12px; }
svg.chart text.tick { fill: var(--muted); }
svg.chart rect.plot { fill: none; stroke: #aab1bd; }
svg.chart line.grid { stroke: #eceef2; }
svg.chart path.line { fill: none; stroke-width: 1.6; stroke-linejoin: round; }
svg.chart line.cursor { stroke: #D55E00; stroke-width: 1.2; }
pre { white-space: pre-wrap; overflow-wrap: anywhere; font-size: 13px; margin: 0; }
@media print { .controls, .hint { display: none; } section { break-inside: avoid; } }
"""

#: The page's script (run once the page is parsed; its SHA-256 is the page's only
#: script-src, so no other script on the page can run).
SCRIPT = r"""
(() => {
  "use strict";
  const data = JSON.parse(document.getElementById("run-data").textContent);
  const canvas = document.getElementById("view");
  const ctx = canvas.getContext("2d");
  const slider = document.getElementById("time");
  const playButton = document.getElementById("play");
  const speed = document.getElementById("speed");
  const readout = document.getElementById("time-readout");
  const cells = [...document.querySelectorAll("[data-joint]")];
  const charts = [...document.querySelectorAll("svg.chart")];
  const S = data.scale, T = data.t, F = data.frames, G = data.ghost, R = data.triad;
  const counts = data.chains, Q = data.q_display;
  const frameCount = T.length;

  // The scene's extent: every point of every frame (and the statics).
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  const grow = (x, y, z) => {
    lo[0] = Math.min(lo[0], x); lo[1] = Math.min(lo[1], y); lo[2] = Math.min(lo[2], z);
    hi[0] = Math.max(hi[0], x); hi[1] = Math.max(hi[1], y); hi[2] = Math.max(hi[2], z);
  };
  for (const f of F) if (f) for (let k = 0; k < f.length; k += 3)
    grow(f[k] * S, f[k + 1] * S, f[k + 2] * S);
  for (const poly of data.statics) for (let k = 0; k < poly.length; k += 3)
    grow(poly[k], poly[k + 1], poly[k + 2]);
  if (!isFinite(lo[0])) { lo.fill(-0.1); hi.fill(0.1); }
  const center = [0, 1, 2].map(i => (lo[i] + hi[i]) / 2);
  const size = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 0.05);
  const ground = lo[2];  // the grid just under the lowest point the run reaches
  const HOME = { yaw: -0.9, pitch: 0.42, dist: size * 2.6 };
  const cam = { ...HOME };
  let index = 0, playing = false, playTime = T[0], lastStamp = null;

  // Per-chain point offsets into a frame's flat array.
  const starts = []; { let s = 0; for (const n of counts) { starts.push(s); s += n; } }

  // The camera: orbit (yaw about +z, pitch above the ground) around the scene's centre.
  let eye, right, up, fwd, focal, W, H;
  function setCamera() {
    const cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
    const cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw);
    const back = [cp * cy, cp * sy, sp];
    eye = center.map((c, i) => c + cam.dist * back[i]);
    fwd = back.map(v => -v);
    right = [fwd[1], -fwd[0], 0];
    const n = Math.hypot(right[0], right[1]) || 1; right = right.map(v => v / n);
    up = [right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
          right[0] * fwd[1] - right[1] * fwd[0]];
    focal = 0.5 * Math.min(W, H) / Math.tan(0.35);
  }
  function project(x, y, z) {
    const d = [x - eye[0], y - eye[1], z - eye[2]];
    const depth = d[0] * fwd[0] + d[1] * fwd[1] + d[2] * fwd[2];
    if (depth < 1e-3) return null;
    const px = d[0] * right[0] + d[1] * right[1] + d[2] * right[2];
    const py = d[0] * up[0] + d[1] * up[1] + d[2] * up[2];
    return [W / 2 + focal * px / depth, H / 2 - focal * py / depth, depth];
  }
  const pointOf = (f, k) => project(f[3 * k] * S, f[3 * k + 1] * S, f[3 * k + 2] * S);

  function line(a, b, width, color, alpha) {
    if (!a || !b) return;
    ctx.globalAlpha = alpha; ctx.strokeStyle = color; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke();
  }
  function disc(p, r, fill, stroke, alpha) {
    if (!p) return;
    ctx.globalAlpha = alpha; ctx.fillStyle = fill; ctx.strokeStyle = stroke;
    ctx.lineWidth = Math.max(1, r * 0.25);
    ctx.beginPath(); ctx.arc(p[0], p[1], r, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
  }

  function drawGrid() {
    const step = Math.pow(10, Math.floor(Math.log10(size / 2)));
    const span = Math.ceil(size * 0.9 / step) * step;
    ctx.lineCap = "butt";
    for (let v = -span; v <= span + 1e-9; v += step) {
      const major = Math.abs(v) < 1e-9;
      const c = major ? "#b9c0cc" : "#e3e6ec";
      line(project(center[0] + v, center[1] - span, ground),
           project(center[0] + v, center[1] + span, ground), 1, c, 1);
      line(project(center[0] - span, center[1] + v, ground),
           project(center[0] + span, center[1] + v, ground), 1, c, 1);
    }
    const o = project(0, 0, ground), axis = size * 0.12;
    line(o, project(axis, 0, ground), 2, "#D55E00", 0.8);
    line(o, project(0, axis, ground), 2, "#009E73", 0.8);
    line(o, project(0, 0, ground + axis), 2, "#0072B2", 0.8);
  }

  function drawTraces() {
    for (let c = 0; c < counts.length; c++) {
      const k = starts[c] + counts[c] - 1;
      for (const [from, to, color, alpha] of [[0, frameCount - 1, "#9aa3b2", 0.5],
                                              [0, index, "#5b6474", 0.9]]) {
        ctx.globalAlpha = alpha; ctx.strokeStyle = color; ctx.lineWidth = 1.5;
        ctx.beginPath(); let pen = false;
        for (let i = from; i <= to; i++) {
          const f = F[i]; const p = f && pointOf(f, k);
          if (!p) { pen = false; continue; }
          if (pen) ctx.lineTo(p[0], p[1]); else ctx.moveTo(p[0], p[1]);
          pen = true;
        }
        ctx.stroke();
      }
    }
  }

  // The arm (or its ghost): every link and joint, far ones first.
  function drawPose(f, ghost) {
    if (!f) return;
    const items = [];
    const radius = size * 0.018 * (ghost ? 0.7 : 1);
    for (let c = 0; c < counts.length; c++) {
      const pts = [];
      for (let j = 0; j < counts[c]; j++) pts.push(pointOf(f, starts[c] + j));
      for (let j = 0; j + 1 < pts.length; j++) {
        const a = pts[j], b = pts[j + 1];
        if (a && b) items.push([(a[2] + b[2]) / 2, "link", a, b]);
      }
      pts.forEach((p, j) => { if (p) items.push([p[2] - 1e-6, j === 0 ? "base" : "joint", p]); });
    }
    items.sort((u, v) => v[0] - u[0]);
    ctx.lineCap = "round";
    for (const [, kind, a, b] of items) {
      const px = focal * radius / a[2];
      if (ghost) {
        if (kind === "link") line(a, b, Math.max(2, 2 * px), "#0072B2", 0.35);
        else disc(a, Math.max(2, 1.2 * px), "#0072B2", "#0072B2", 0.3);
      } else if (kind === "link") {
        line(a, b, Math.max(3, 2 * px), "#3b4656", 1);
        line(a, b, Math.max(1, 0.9 * px), "#5f6d82", 1);
      } else {
        disc(a, Math.max(3, (kind === "base" ? 1.8 : 1.4) * px),
             kind === "base" ? "#3b4656" : "#f4f5f7", "#1d2330", 1);
      }
    }
    ctx.globalAlpha = 1;
  }

  function drawTriad(f, r) {
    if (!f || !r) return;
    const k = starts[0] + counts[0] - 1;
    const x = f[3 * k] * S, y = f[3 * k + 1] * S, z = f[3 * k + 2] * S;
    const o = project(x, y, z), len = size * 0.1 / 100;
    ["#D55E00", "#009E73", "#0072B2"].forEach((color, a) => line(o,
      project(x + r[a] * len, y + r[a + 3] * len, z + r[a + 6] * len), 2, color, 0.9));
  }

  function draw() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr));
    const h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    W = w; H = h; setCamera();
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.globalAlpha = 1; ctx.fillStyle = "#fbfbfd"; ctx.fillRect(0, 0, W, H);
    drawGrid();
    for (const poly of data.statics) {
      const pts = [];
      for (let k = 0; k < poly.length; k += 3) pts.push(project(poly[k], poly[k + 1], poly[k + 2]));
      pts.forEach((p, j) => line(p, pts[(j + 1) % pts.length], Math.max(2, W / 300), "#3b4656", 1));
    }
    drawTraces();
    if (G) drawPose(G[index], true);
    drawPose(F[index], false);
    if (R) drawTriad(F[index], R[index]);
    ctx.globalAlpha = 1;
  }

  function show(i, fromPlay) {
    index = Math.max(0, Math.min(frameCount - 1, i | 0));
    if (!fromPlay) playTime = T[index];
    slider.value = String(index);
    const t = T[index];
    readout.textContent = "t = " + t.toFixed(3) + " s";
    const q = Q[index];
    cells.forEach(td => {
      const v = q ? q[+td.dataset.joint] : null;
      td.textContent = v === null || v === undefined ? "–" : v.toFixed(1) + " " + td.dataset.unit;
    });
    for (const svg of charts) {
      const t0 = +svg.dataset.t0, t1 = +svg.dataset.t1, x0 = +svg.dataset.x0, x1 = +svg.dataset.x1;
      const x = String(x0 + Math.max(0, Math.min(1, (t - t0) / (t1 - t0))) * (x1 - x0));
      const cursor = svg.querySelector("line.cursor");
      cursor.setAttribute("x1", x); cursor.setAttribute("x2", x);
    }
    draw();
  }

  function frameAt(t) {  // last frame at or before t
    let a = 0, b = frameCount - 1;
    while (a < b) { const m = (a + b + 1) >> 1; if (T[m] <= t) a = m; else b = m - 1; }
    return a;
  }
  function tick(stamp) {
    if (!playing) return;
    if (lastStamp !== null) playTime += (stamp - lastStamp) / 1000 * (+speed.value || 1);
    lastStamp = stamp;
    if (playTime >= T[frameCount - 1]) { show(frameCount - 1, true); setPlaying(false); return; }
    show(frameAt(playTime), true);
    requestAnimationFrame(tick);
  }
  function setPlaying(on) {
    playing = on; lastStamp = null;
    playButton.textContent = on ? "Pause" : "Play";
    playButton.setAttribute("aria-pressed", on ? "true" : "false");
    if (on) {
      if (index >= frameCount - 1) { show(0); }
      playTime = T[index];
      requestAnimationFrame(tick);
    }
  }

  slider.max = String(frameCount - 1);
  slider.addEventListener("input", () => { setPlaying(false); show(+slider.value); });
  playButton.addEventListener("click", () => setPlaying(!playing));

  // Orbit with one pointer (mouse or finger), zoom with the wheel or two fingers.
  const pointers = new Map();
  let pinch = null;
  canvas.addEventListener("pointerdown", e => {
    canvas.setPointerCapture(e.pointerId); pointers.set(e.pointerId, [e.clientX, e.clientY]);
    canvas.style.cursor = "grabbing";
  });
  const release = e => {
    pointers.delete(e.pointerId); pinch = null;
    if (!pointers.size) canvas.style.cursor = "grab";
  };
  canvas.addEventListener("pointerup", release);
  canvas.addEventListener("pointercancel", release);
  canvas.addEventListener("pointermove", e => {
    const last = pointers.get(e.pointerId);
    if (!last) return;
    pointers.set(e.pointerId, [e.clientX, e.clientY]);
    if (pointers.size === 2) {
      const [p, q] = [...pointers.values()];
      const d = Math.hypot(p[0] - q[0], p[1] - q[1]);
      if (pinch) cam.dist = Math.max(size * 0.3, Math.min(size * 20, cam.dist * pinch / d));
      pinch = d;
    } else {
      cam.yaw -= (e.clientX - last[0]) * 0.01;
      cam.pitch = Math.max(-1.2, Math.min(1.5, cam.pitch + (e.clientY - last[1]) * 0.01));
    }
    draw();
  });
  canvas.addEventListener("wheel", e => {
    e.preventDefault();
    cam.dist = Math.max(size * 0.3, Math.min(size * 20, cam.dist * Math.exp(e.deltaY * 0.001)));
    draw();
  }, { passive: false });
  canvas.addEventListener("dblclick", () => { Object.assign(cam, HOME); draw(); });
  canvas.addEventListener("keydown", e => {
    const step = { ArrowLeft: [0.1, 0], ArrowRight: [-0.1, 0], ArrowUp: [0, 0.1],
                   ArrowDown: [0, -0.1] }[e.key];
    if (step) {
      e.preventDefault(); cam.yaw += step[0];
      cam.pitch = Math.max(-1.2, Math.min(1.5, cam.pitch + step[1])); draw();
    } else if (e.key === " ") { e.preventDefault(); setPlaying(!playing); }
  });
  window.addEventListener("resize", draw);
  show(0);
  document.body.dataset.ready = "1";
})();
"""
