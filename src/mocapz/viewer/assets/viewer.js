"use strict";
(() => {
const D = JSON.parse(document.getElementById("mocapz-data").textContent);
const $ = (id) => document.getElementById(id);

// ------------------------------------------------------------------------------------------- data
function bytes(s) {
  const bin = atob(s), u = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) u[i] = bin.charCodeAt(i);
  return u;
}
const f32 = (s) => new Float32Array(bytes(s).buffer);
function positions(s) {
  const q = new Int16Array(bytes(s).buffer), out = new Float32Array(q.length), lo = D.quant.lo, st = D.quant.step;
  for (let i = 0; i < q.length; i++) {
    const k = i % 3;
    out[i] = q[i] === -32768 ? NaN : lo[k] + (q[i] + 32767) * st[k];
  }
  return out;
}
const F = D.frames, P = D.points, HAS_DEC = D.decoded !== null;
const A = positions(D.original), B = HAS_DEC ? positions(D.decoded) : null;
const EQ = HAS_DEC ? bytes(D.errors) : null;
const FMAX = f32(D.frame_max), FMEAN = f32(D.frame_mean), CEN = f32(D.center);
const BONES = D.bones, NB = BONES.length / 2, MARKERS = D.kind === "markers";
const err = (f, p) => { const q = EQ[f * P + p]; return q === 255 ? NaN : (q / 254) * D.err_max; };
const fmtLen = (v) => (isFinite(v) ? (v * D.unit_scale).toPrecision(3) + " " + D.unit : "n/a");

// ------------------------------------------------------------------------------------------ state
const DPR = Math.max(1, window.devicePixelRatio || 1);
const BG = [21, 24, 29];
const cam = { yaw: D.view.yaw, pitch: D.view.pitch, dist: D.view.dist, fov: (40 * Math.PI) / 180, pan: [0, 0, 0] };
let frame = 0, playing = false, speed = 1, t0 = 0, fStart = 0, dirty = true, selected = -1;
let mode = HAS_DEC ? "all" : "original", scale = D.scales[0][1] > 0 ? D.scales[0][1] : 1e-12, follow = true;
let picks = [], heat = null, heatScale = -1, drawn = 0;
const NEAR = D.height * 0.02;
const meanCenter = [0, 0, 0];
for (let f = 0; f < F; f++) for (let k = 0; k < 3; k++) meanCenter[k] += CEN[3 * f + k] / F;

function errColor(e, alpha) {
  if (!(e >= 0)) return `rgba(150,150,150,${alpha})`;
  const r = Math.min(e / scale, 1);
  return `hsla(${(120 * (1 - r)).toFixed(1)},85%,${(50 + 5 * (1 - r)).toFixed(1)}%,${alpha})`;
}
function errRGB(e) {
  if (!(e >= 0)) return [90, 90, 90];
  const r = Math.min(e / scale, 1), h = (120 * (1 - r)) / 360, l = 0.5 + 0.05 * (1 - r), s = 0.85;
  const q = l < 0.5 ? l * (1 + s) : l + s - l * s, p = 2 * l - q;
  const ch = (t) => {
    t = (t + 1) % 1;
    const v = t < 1 / 6 ? p + (q - p) * 6 * t : t < 1 / 2 ? q : t < 2 / 3 ? p + (q - p) * (2 / 3 - t) * 6 : p;
    return Math.round(255 * v);
  };
  return [ch(h + 1 / 3), ch(h), ch(h - 1 / 3)];
}

// ----------------------------------------------------------------------------------------- camera
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
function target(f) {
  const c = follow ? [CEN[3 * f], CEN[3 * f + 1], CEN[3 * f + 2]] : meanCenter;
  return [c[0] + cam.pan[0], c[1] + cam.pan[1], c[2] + cam.pan[2]];
}
function makeView(t, w, h) {
  const cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw), cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
  const eye = [t[0] + cam.dist * cp * cy, t[1] + cam.dist * cp * sy, t[2] + cam.dist * sp];
  const fw = [-cp * cy, -cp * sy, -sp], rt = [-sy, cy, 0];
  const up = [rt[1] * fw[2] - rt[2] * fw[1], rt[2] * fw[0] - rt[0] * fw[2], rt[0] * fw[1] - rt[1] * fw[0]];
  return { eye, fw, rt, up, focal: (0.5 * h) / Math.tan(cam.fov / 2), cx: w / 2, cy: h / 2 };
}
function toCam(V, x, y, z) {
  const d = [x - V.eye[0], y - V.eye[1], z - V.eye[2]];
  return [dot(d, V.rt), dot(d, V.up), dot(d, V.fw)];
}
const proj = (V, c) => [V.cx + (c[0] * V.focal) / c[2], V.cy - (c[1] * V.focal) / c[2]];
function clipNear(a, b) {
  const t = (NEAR - a[2]) / (b[2] - a[2]);
  return [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), NEAR];
}
function segment(g, V, a, b) {
  if (a[2] < NEAR && b[2] < NEAR) return;
  if (a[2] < NEAR) a = clipNear(a, b);
  else if (b[2] < NEAR) b = clipNear(b, a);
  const p = proj(V, a), q = proj(V, b);
  g.moveTo(p[0], p[1]);
  g.lineTo(q[0], q[1]);
}
function camPoints(V, X, f, flatZ) {
  const out = new Array(P), o = f * P * 3;
  for (let p = 0; p < P; p++) {
    const x = X[o + 3 * p], y = X[o + 3 * p + 1], z = flatZ === undefined ? X[o + 3 * p + 2] : flatZ;
    out[p] = isNaN(x) || isNaN(y) || isNaN(z) ? null : toCam(V, x, y, z);
  }
  return out;
}

// ---------------------------------------------------------------------------------------- drawing
function drawGrid(g, V, t) {
  const G = D.grid, n = 8, cx = Math.round(t[0] / G) * G, cy = Math.round(t[1] / G) * G, z = D.floor;
  g.beginPath();
  for (let i = -n; i <= n; i++) {
    segment(g, V, toCam(V, cx + i * G, cy - n * G, z), toCam(V, cx + i * G, cy + n * G, z));
    segment(g, V, toCam(V, cx - n * G, cy + i * G, z), toCam(V, cx + n * G, cy + i * G, z));
  }
  g.strokeStyle = "rgba(130,142,160,0.22)";
  g.lineWidth = DPR;
  g.stroke();
}
function drawShadow(g, V, X, f) {
  const S = camPoints(V, X, f, D.floor);
  g.beginPath();
  for (let b = 0; b < NB; b++) {
    const u = S[BONES[2 * b]], v = S[BONES[2 * b + 1]];
    if (u && v) segment(g, V, u, v);
  }
  g.strokeStyle = "rgba(0,0,0,0.35)";
  g.lineWidth = (MARKERS ? 1.5 : 4) * DPR;
  g.lineCap = "round";
  g.stroke();
}
// style: {color: fixed colour or null for error colours, width, alpha, radius}
function drawFigure(g, V, X, f, st, pane, pickable) {
  const C = camPoints(V, X, f), items = [];
  for (let b = 0; b < NB; b++) {
    const i = BONES[2 * b], j = BONES[2 * b + 1];
    if (C[i] && C[j] && (C[i][2] > NEAR || C[j][2] > NEAR)) items.push([0.5 * (C[i][2] + C[j][2]), 0, i, j]);
  }
  for (let p = 0; p < P; p++) if (C[p] && C[p][2] > NEAR) items.push([C[p][2], 1, p, p]);
  items.sort((a, b) => b[0] - a[0] || a[1] - b[1] || a[2] - b[2]);
  const persp = (z) => Math.min(2.2, Math.max(0.45, cam.dist / z));
  for (const [z, kind, i, j] of items) {
    if (kind === 0) {
      const e = st.color ? 0 : 0.5 * (err(f, i) + err(f, j));
      g.beginPath();
      segment(g, V, C[i], C[j]);
      g.strokeStyle = st.color || errColor(e, st.alpha);
      if (MARKERS) g.globalAlpha = 0.5;
      g.lineWidth = st.width * DPR * persp(z);
      g.lineCap = "round";
      g.stroke();
      g.globalAlpha = 1;
    } else {
      const q = proj(V, C[i]), r = st.radius * DPR * persp(z);
      g.beginPath();
      g.arc(q[0], q[1], r, 0, 2 * Math.PI);
      g.fillStyle = st.color || errColor(err(f, i), st.alpha);
      g.fill();
      if (pickable) picks.push({ x: q[0] + pane.x, y: q[1], p: i, r });
      if (i === selected) {
        g.beginPath();
        g.arc(q[0], q[1], r + 5 * DPR, 0, 2 * Math.PI);
        g.strokeStyle = "#6fd3ff";
        g.lineWidth = 2 * DPR;
        g.stroke();
      }
    }
  }
}
function drawDisplacements(g, V, f) {
  const CA = camPoints(V, A, f), CB = camPoints(V, B, f);
  g.beginPath();
  for (let p = 0; p < P; p++) if (CA[p] && CB[p] && err(f, p) > 0.05 * scale) segment(g, V, CA[p], CB[p]);
  g.strokeStyle = "rgba(255,90,90,0.9)";
  g.lineWidth = 1.5 * DPR;
  g.stroke();
}
const ORIG = "rgb(160,182,212)";
const styles = {
  original: { color: ORIG, width: MARKERS ? 1.3 : 3.2, radius: 3, alpha: 1 },
  decoded: { color: null, width: MARKERS ? 1.3 : 3.2, radius: 3, alpha: 1 },
  ghost: { color: "rgba(225,232,245,0.32)", width: MARKERS ? 1 : 7, radius: 5, alpha: 1 },
  over: { color: null, width: MARKERS ? 1 : 2.2, radius: 2.4, alpha: 1 },
};
function panes() {
  if (!HAS_DEC) return ["original"];
  return { all: ["original", "decoded", "overlay"], side: ["original", "decoded"], overlay: ["overlay"],
    original: ["original"], decoded: ["decoded"] }[mode];
}
const TITLES = { original: "original", decoded: D.decoded_label, overlay: "overlay: original (white) + decoded" };
function drawView() {
  const c = $("view"), w = c.width, h = c.height, g = c.getContext("2d");
  g.fillStyle = `rgb(${BG.join(",")})`;
  g.fillRect(0, 0, w, h);
  picks = [];
  const list = panes(), pw = w / list.length, t = target(frame);
  list.forEach((name, k) => {
    const pane = { x: Math.round(k * pw), w: Math.round((k + 1) * pw) - Math.round(k * pw) };
    g.save();
    g.beginPath();
    g.rect(pane.x, 0, pane.w, h);
    g.clip();
    g.translate(pane.x, 0);
    const V = makeView(t, pane.w, h);
    drawGrid(g, V, t);
    if (name === "decoded") {
      drawShadow(g, V, B, frame);
      drawFigure(g, V, B, frame, styles.decoded, pane, true);
    } else if (name === "original") {
      drawShadow(g, V, A, frame);
      drawFigure(g, V, A, frame, styles.original, pane, !HAS_DEC);
    } else {
      drawShadow(g, V, A, frame);
      drawFigure(g, V, A, frame, styles.ghost, pane, false);
      drawDisplacements(g, V, frame);
      drawFigure(g, V, B, frame, styles.over, pane, true);
    }
    g.fillStyle = "#cfd6e0";
    g.font = `${12 * DPR}px system-ui, sans-serif`;
    g.fillText(TITLES[name], 10 * DPR, 18 * DPR);
    g.restore();
    if (k > 0) {
      g.fillStyle = "#2c323c";
      g.fillRect(pane.x - DPR, 0, 2 * DPR, h);
    }
  });
}
function heatImage() {
  if (heat && heatScale === scale) return heat;
  const cols = Math.min(F, 4096), img = new ImageData(cols, P);
  for (let x = 0; x < cols; x++) {
    const f = Math.floor((x * F) / cols);
    for (let p = 0; p < P; p++) {
      const rgb = errRGB(err(f, p)), o = 4 * (p * cols + x);
      img.data[o] = rgb[0]; img.data[o + 1] = rgb[1]; img.data[o + 2] = rgb[2]; img.data[o + 3] = 255;
    }
  }
  heat = document.createElement("canvas");
  heat.width = cols;
  heat.height = P;
  heat.getContext("2d").putImageData(img, 0, 0);
  heatScale = scale;
  return heat;
}
const stripLayout = (c) => ({ l: 8 * DPR, r: c.width - 8 * DPR, top: 16 * DPR, curveH: 52 * DPR, gap: 6 * DPR });
let stripCache = null, stripKey = "";
function stripBackground(c) {
  // Everything but the play head, redrawn only when the size, colour scale or selected point change.
  const key = [c.width, c.height, scale, selected].join(",");
  if (stripCache && stripKey === key) return stripCache;
  const w = c.width, h = c.height, L = stripLayout(c), X = (f) => L.l + ((L.r - L.l) * (f + 0.5)) / F;
  stripCache = stripCache || document.createElement("canvas");
  stripCache.width = w;
  stripCache.height = h;
  stripKey = key;
  const g = stripCache.getContext("2d");
  g.fillStyle = `rgb(${BG.join(",")})`;
  g.fillRect(0, 0, w, h);
  g.font = `${11 * DPR}px system-ui, sans-serif`;
  if (!HAS_DEC) {
    g.fillStyle = "#8a94a3";
    g.fillText("no decoded motion: give a second file to see the error over time", L.l, 21 * DPR);
    return stripCache;
  }
  let ymax = 0;
  for (let f = 0; f < F; f++) ymax = Math.max(ymax, FMAX[f]);
  if (!(ymax > 0)) ymax = 1;
  const base = L.top + L.curveH, Y = (v) => base - (Math.min(v, ymax) / ymax) * L.curveH;
  g.beginPath();
  g.moveTo(X(0), base);
  for (let f = 0; f < F; f++) g.lineTo(X(f), Y(FMEAN[f]));
  g.lineTo(X(F - 1), base);
  g.closePath();
  g.fillStyle = "rgba(255,170,60,0.45)";
  g.fill();
  g.beginPath();
  for (let f = 0; f < F; f++) (f ? g.lineTo : g.moveTo).call(g, X(f), Y(FMAX[f]));
  g.strokeStyle = "rgb(255,80,80)";
  g.lineWidth = 1.5 * DPR;
  g.stroke();
  if (selected >= 0) {
    g.beginPath();
    for (let f = 0; f < F; f++) (f ? g.lineTo : g.moveTo).call(g, X(f), Y(err(f, selected) || 0));
    g.strokeStyle = "#6fd3ff";
    g.stroke();
  }
  g.fillStyle = "#c0c8d4";
  let txt = `error over time: max (red) ${fmtLen(ymax)} at worst, mean (orange)`;
  if (selected >= 0) txt += `, ${D.names[selected]} (blue)`;
  g.fillText(txt + "; below: error of every point (rows) over time", L.l, 12 * DPR);
  const hy = base + L.gap, hh = h - hy - 4 * DPR;
  g.imageSmoothingEnabled = false;
  if (hh > 2) g.drawImage(heatImage(), L.l, hy, L.r - L.l, hh);
  if (selected >= 0 && hh > 2) {
    g.strokeStyle = "#6fd3ff";
    g.lineWidth = DPR;
    g.strokeRect(L.l, hy + (hh * selected) / P, L.r - L.l, Math.max(hh / P, DPR));
  }
  return stripCache;
}
function drawStrip() {
  const c = $("strip"), g = c.getContext("2d"), L = stripLayout(c);
  g.drawImage(stripBackground(c), 0, 0);
  g.fillStyle = "#ffffff";
  g.fillRect(L.l + ((L.r - L.l) * (frame + 0.5)) / F - DPR, L.top, 2 * DPR, c.height - L.top);
}

// ------------------------------------------------------------------------------------------ panels
const srcTime = (f) => (D.first_frame + f * D.step) / D.source_fps;
function updateCounter() {
  let s = `frame ${frame + 1} / ${F}  \u00b7  ${srcTime(frame).toFixed(3)} s`;
  if (D.step > 1 || D.first_frame > 0) s += `  (source frame ${D.first_frame + frame * D.step + 1})`;
  if (HAS_DEC) s += `  \u00b7  max ${fmtLen(FMAX[frame])}`;
  $("counter").textContent = s;
  $("scrub").value = String(frame);
}
function draw() {
  drawView();
  drawStrip();
  updateCounter();
  drawn++;
  document.body.dataset.frame = String(frame);
  document.body.dataset.playing = playing ? "1" : "0";
}
function buildPanels() {
  document.title = `mocapz view: ${D.name}`;
  $("title").textContent = D.name;
  for (const [k, v] of D.figures) {
    const d = document.createElement("span");
    d.className = "fig";
    const b = document.createElement("b");
    b.textContent = k;
    d.append(b, v);
    $("figs").append(d);
  }
  for (const n of D.notes) {
    const d = document.createElement("div");
    d.textContent = n;
    $("notes").append(d);
  }
  const modes = HAS_DEC ? [["all", "side by side + overlay"], ["side", "side by side"], ["overlay", "overlay"],
    ["original", "original only"], ["decoded", "decoded only"]] : [["original", "original"]];
  for (const [v, t] of modes) $("mode").add(new Option(t, v));
  D.scales.forEach(([t, v], i) => $("scale").add(new Option(t, String(i))));
  $("scrub").max = String(F - 1);
  if (!HAS_DEC) {
    $("strip").style.height = "34px";
    $("side").style.display = "none";
    $("legend").style.display = "none";
    $("scale").parentElement.style.display = "none";
  }
  const rows = D.point_order.slice(0, 40);
  const pmax = Math.max(1e-300, ...D.point_max.map((v) => v || 0));
  for (const p of rows) {
    const r = document.createElement("div");
    r.className = "row";
    r.dataset.p = String(p);
    const nm = document.createElement("span"), bar = document.createElement("span"), v = document.createElement("span");
    nm.className = "nm"; nm.textContent = D.names[p]; nm.title = D.names[p];
    bar.className = "bar";
    const fill = document.createElement("i");
    fill.style.width = `${(100 * (D.point_max[p] || 0)) / pmax}%`;
    fill.style.background = "rgb(255,96,80)";
    bar.append(fill);
    v.className = "v"; v.textContent = fmtLen(D.point_max[p]);
    r.append(nm, bar, v);
    r.addEventListener("click", () => select(selected === p ? -1 : p));
    $("points").append(r);
  }
  updateLegend();
}
function updateLegend() {
  $("scalemax").textContent = `\u2265 ${fmtLen(scale)}`;
  $("legendnote").textContent =
    D.err_max > 0 ? `(clip max error ${fmtLen(D.err_max)})` : "(no error: identical motions)";
}
function select(p) {
  selected = p;
  for (const r of document.querySelectorAll(".row")) r.classList.toggle("sel", Number(r.dataset.p) === p);
  dirty = true;
}

// ------------------------------------------------------------------------------------------ control
function resize() {
  for (const id of ["view", "strip"]) {
    const c = $(id), w = Math.round(c.clientWidth * DPR), h = Math.round(c.clientHeight * DPR);
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
  }
  dirty = true;
}
function play() { if (!playing) { playing = true; t0 = performance.now(); fStart = frame; } setPlayLabel(); }
function pause() { playing = false; setPlayLabel(); dirty = true; }
function setPlayLabel() { $("play").innerHTML = playing ? "&#10074;&#10074; pause" : "&#9654; play"; }
function seek(f) {
  frame = Math.max(0, Math.min(F - 1, Math.round(f)));
  if (playing) { t0 = performance.now(); fStart = frame; }
  dirty = true;
}
function resetCamera() {
  cam.yaw = D.view.yaw; cam.pitch = D.view.pitch; cam.dist = D.view.dist; cam.pan = [0, 0, 0];
  dirty = true;
}
function tick(now) {
  if (playing) {
    const f = Math.floor(fStart + ((now - t0) / 1000) * D.fps * speed);
    if (f !== frame) { frame = ((f % F) + F) % F; dirty = true; }
  }
  if (dirty) { dirty = false; draw(); }
  requestAnimationFrame(tick);
}
$("play").addEventListener("click", () => (playing ? pause() : play()));
$("scrub").addEventListener("input", (e) => seek(Number(e.target.value)));
$("speed").addEventListener("change", (e) => {
  speed = Number(e.target.value);
  if (playing) { t0 = performance.now(); fStart = frame; }
});
$("mode").addEventListener("change", (e) => { mode = e.target.value; dirty = true; });
$("scale").addEventListener("change", (e) => {
  const v = D.scales[Number(e.target.value)][1];
  scale = v > 0 ? v : 1e-12;
  updateLegend();
  dirty = true;
});
$("follow").addEventListener("change", (e) => { follow = e.target.checked; cam.pan = [0, 0, 0]; dirty = true; });
$("reset").addEventListener("click", resetCamera);
const view = $("view");
let drag = null;
view.addEventListener("contextmenu", (e) => e.preventDefault());
view.addEventListener("pointerdown", (e) => {
  drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2, moved: false };
  view.setPointerCapture(e.pointerId);
  view.classList.add("dragging");
});
view.addEventListener("pointermove", (e) => {
  if (!drag) { hover(e); return; }
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  if (Math.abs(dx) + Math.abs(dy) > 2) drag.moved = true;
  drag.x = e.clientX; drag.y = e.clientY;
  if (drag.pan) {
    const V = makeView(target(frame), view.width, view.height), k = (cam.dist / V.focal) * DPR;
    for (let i = 0; i < 3; i++) cam.pan[i] += -dx * k * V.rt[i] + dy * k * V.up[i];
  } else {
    cam.yaw -= dx * 0.008;
    cam.pitch = Math.max(-1.2, Math.min(1.45, cam.pitch + dy * 0.008));
  }
  $("tip").style.display = "none";
  dirty = true;
});
view.addEventListener("pointerup", (e) => {
  if (drag && !drag.moved) {
    const hit = pick(e);
    select(hit === null ? -1 : hit === selected ? -1 : hit);
  }
  drag = null;
  view.classList.remove("dragging");
});
view.addEventListener("wheel", (e) => {
  e.preventDefault();
  cam.dist = Math.max(D.height * 0.2, Math.min(D.height * 60, cam.dist * Math.exp(e.deltaY * 0.0012)));
  dirty = true;
}, { passive: false });
view.addEventListener("dblclick", resetCamera);
function pick(e) {
  const r = view.getBoundingClientRect(), x = (e.clientX - r.left) * DPR, y = (e.clientY - r.top) * DPR;
  let best = null, bd = (10 * DPR) ** 2;
  for (const q of picks) {
    const d = (q.x - x) ** 2 + (q.y - y) ** 2;
    if (d < bd) { bd = d; best = q.p; }
  }
  return best;
}
function hover(e) {
  const p = pick(e), tip = $("tip");
  if (p === null) { tip.style.display = "none"; return; }
  let s = D.names[p];
  if (HAS_DEC) s += `: ${fmtLen(err(frame, p))} now, ${fmtLen(D.point_max[p])} at worst`;
  tip.textContent = s;
  const r = view.getBoundingClientRect();
  tip.style.left = `${e.clientX - r.left + 14}px`;
  tip.style.top = `${e.clientY - r.top + 10}px`;
  tip.style.display = "block";
}
const strip = $("strip");
let stripDrag = false;
function stripSeek(e) {
  const r = strip.getBoundingClientRect(), L = stripLayout(strip);
  const x = (e.clientX - r.left) * DPR;
  seek(((x - L.l) / (L.r - L.l)) * F - 0.5);
}
strip.addEventListener("pointerdown", (e) => { stripDrag = true; strip.setPointerCapture(e.pointerId); stripSeek(e); });
strip.addEventListener("pointermove", (e) => { if (stripDrag) stripSeek(e); });
strip.addEventListener("pointerup", () => { stripDrag = false; });
window.addEventListener("keydown", (e) => {
  const t = e.target;
  if (t instanceof HTMLSelectElement || (t instanceof HTMLInputElement && t.type !== "checkbox")) return;
  if (e.key === " " && (t instanceof HTMLButtonElement || t instanceof HTMLInputElement)) return;  // native click
  const n = e.shiftKey ? 10 : 1;
  if (e.key === " ") { e.preventDefault(); playing ? pause() : play(); }
  else if (e.key === "ArrowRight") { e.preventDefault(); pause(); seek(frame + n); }
  else if (e.key === "ArrowLeft") { e.preventDefault(); pause(); seek(frame - n); }
  else if (e.key === "Home") seek(0);
  else if (e.key === "End") seek(F - 1);
});
window.addEventListener("resize", resize);

// ---------------------------------------------------------------------------- state, for tests
function inkFraction(c) {
  const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
  let ink = 0, n = 0;
  for (let i = 0; i < d.length; i += 4 * 7) {
    n++;
    if (Math.abs(d[i] - BG[0]) + Math.abs(d[i + 1] - BG[1]) + Math.abs(d[i + 2] - BG[2]) > 30) ink++;
  }
  return n ? ink / n : 0;
}
window.mocapzViewer = {
  state: () => ({ frame, frames: F, playing, mode, drawn, yaw: cam.yaw, selected, hasDecoded: HAS_DEC,
    viewInk: inkFraction($("view")), stripInk: inkFraction($("strip")) }),
  play, pause, seek: (f) => { seek(f); draw(); },
};

buildPanels();
resize();
draw();
document.body.dataset.ready = "1";
if (/(^|[#&?])play\b/.test(location.hash + location.search)) play();
requestAnimationFrame(tick);
})();
