// vibroscope studio: the page. Plain JavaScript drawing on canvas; every
// number comes from the server's API (the library's recipes).
"use strict";

const $ = (id) => document.getElementById(id);
const TOKEN = new URLSearchParams(location.search).get("token");

// Everything the page shows, readable by the end-to-end test.
const S = {
  video: null, fps: null, info: null, scale: 1, frameIndex: 0,
  regions: [], sel: -1, motion: null, mode: null, grey: null,
  motionSeq: 0, modeSeq: 0, errorSeq: 0, lastError: null, busy: 0,
  sound: null, soundSeq: 0, soundBuffer: null, soundStarted: false, audioCtx: null,
  damp: null, dampSeq: 0, specDrag: null,
  // A mask painted on the frame (its own frame-size canvas) and whether
  // the mouse paints; S.sel === MASK selects it.
  mask: null, painting: false,
};
const MASK = -2;
window.studio = S;

function url(path, params) {
  const q = new URLSearchParams(params || {});
  if (TOKEN) q.set("token", TOKEN);
  const s = q.toString();
  return s ? path + "?" + s : path;
}

function showError(msg) {
  S.lastError = msg; S.errorSeq++;
  const e = $("error"); e.textContent = msg; e.hidden = false;
}
function clearError() { $("error").hidden = true; }
function status(msg) { $("status").textContent = msg; }

async function api(path, params, body) {
  S.busy++;
  try {
    const opts = body === undefined ? {} :
      { method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(body) };
    let r;
    try { r = await fetch(url(path, params), opts); }
    catch (e) { throw new Error("the studio server does not answer (" + e.message + ")"); }
    if (!r.ok) {
      let msg = r.status + " " + r.statusText;
      try { const j = await r.json(); if (j.error) msg = j.error; } catch (_) { /* not JSON */ }
      throw new Error(msg);
    }
    return r;
  } finally { S.busy--; }
}

// Millimetres per pixel typed in the header, or null; undefined (and the
// error shown) when it is not a number.
function scaleParam() {
  const t = $("mmpx").value.trim();
  if (t === "") return null;
  const v = Number(t);
  if (!isFinite(v)) { showError(`scale: "${t}" is not a number of millimetres per pixel`); return undefined; }
  return v;
}

function fpsParam() {
  const v = parseFloat($("fps").value);
  return isFinite(v) && v > 0 ? v : null;
}

// ---- opening a video and scrubbing ----
async function openVideo() {
  clearError();
  const video = $("video").value.trim();
  const params = { video };
  const fps = fpsParam();
  if (fps) params.fps = fps;
  try {
    const info = await (await api("/api/info", params)).json();
    S.video = video; S.fps = fps; S.info = info; S.regions = []; S.sel = -1; S.mode = null; S.mask = null;
    const w = info.width, h = info.height;
    S.scale = Math.max(1, Math.min(8, Math.floor(560 / w)));
    const cw = w * S.scale, ch = h * S.scale;
    for (const id of ["frame", "modal"]) {
      const c = $(id); c.width = w; c.height = h; c.style.width = cw + "px"; c.style.height = ch + "px";
    }
    const o = $("overlay"); o.width = cw; o.height = ch; o.style.width = cw + "px"; o.style.height = ch + "px";
    $("modal").hidden = true; $("modepanel").hidden = true;
    S.sound = null; $("soundgram").hidden = true; $("audio").removeAttribute("src"); $("listenstatus").textContent = "";
    S.damp = null; $("damppanel").hidden = true;
    IDV.engine = null; IDV.basis = null; IDV.on = false; $("idvon").checked = false; $("idvon").disabled = true;
    $("idvinfo").textContent = ""; $("overlay").style.cursor = "crosshair";
    $("scrub").max = Math.max(0, (info.frames || 1) - 1); $("scrub").value = 0;
    status(`${info.format} ${w}x${h}, ${info.frames ?? "?"} frames at ${info.fps ?? "?"} Hz`);
    await loadFrame(0);
    drawRegions();
    await loadMotion();
  } catch (e) { showError(e.message); }
}

async function loadFrame(i) {
  const r = await api("/api/frame", { video: S.video, i });
  const blob = await r.blob();
  const bmp = await createImageBitmap(blob);
  const c = $("frame"), g = c.getContext("2d");
  g.drawImage(bmp, 0, 0);
  const d = g.getImageData(0, 0, c.width, c.height).data;
  S.grey = new Uint8ClampedArray(c.width * c.height);
  for (let k = 0; k < S.grey.length; k++) S.grey[k] = d[4 * k];
  S.frameIndex = i; $("frameno").textContent = "frame " + i;
}

// ---- regions ----
let drag = null;
function framePoint(ev) {
  const o = $("overlay"), b = o.getBoundingClientRect();
  const x = Math.floor((ev.clientX - b.left) / S.scale), y = Math.floor((ev.clientY - b.top) / S.scale);
  return [Math.max(0, Math.min(S.info.width, x)), Math.max(0, Math.min(S.info.height, y))];
}
function dragRoi() {
  const [x0, y0] = drag.a, [x1, y1] = drag.b;
  return [Math.min(x0, x1), Math.min(y0, y1), Math.abs(x1 - x0), Math.abs(y1 - y0)];
}
// The selected region as the API takes it: a rectangle, a painted mask
// (PNG data URL), or neither (the whole frame); and its name.
function selection() {
  if (S.sel === MASK && S.mask) return { roi: null, mask: S.mask.canvas.toDataURL("image/png"), name: "the mask" };
  if (S.sel >= 0) return { roi: S.regions[S.sel], mask: null, name: `R${S.sel + 1}` };
  return { roi: null, mask: null, name: "whole frame" };
}
function paintAt(ev) {
  if (!S.mask) {
    const c = document.createElement("canvas"); c.width = S.info.width; c.height = S.info.height;
    S.mask = { canvas: c };
  }
  const [x, y] = framePoint(ev), g = S.mask.canvas.getContext("2d");
  g.fillStyle = "#fff"; g.beginPath(); g.arc(x + 0.5, y + 0.5, +$("brush").value, 0, 2 * Math.PI); g.fill();
  drawRegions();
}
function drawRegions() {
  const o = $("overlay"), g = o.getContext("2d"), s = S.scale;
  g.clearRect(0, 0, o.width, o.height);
  if (S.mask) {
    g.save(); g.globalAlpha = S.sel === MASK ? 0.45 : 0.2; g.imageSmoothingEnabled = false;
    g.drawImage(S.mask.canvas, 0, 0, o.width, o.height); g.restore();
  }
  g.lineWidth = 2; g.font = "12px sans-serif";
  S.regions.forEach((r, k) => {
    g.strokeStyle = k === S.sel ? "#ffcc33" : "#33ccff";
    g.strokeRect(r[0] * s + 1, r[1] * s + 1, r[2] * s - 2, r[3] * s - 2);
    g.fillStyle = g.strokeStyle; g.fillText("R" + (k + 1), r[0] * s + 4, r[1] * s + 14);
  });
  if (drag) {
    const r = dragRoi(); g.strokeStyle = "#fff"; g.setLineDash([4, 3]);
    g.strokeRect(r[0] * s, r[1] * s, r[2] * s, r[3] * s); g.setLineDash([]);
  }
  const box = $("regions"); box.innerHTML = "";
  const add = (label, k) => {
    const b = document.createElement("button"); b.className = "region" + (k === S.sel ? " sel" : "");
    b.textContent = label; b.onclick = () => { S.sel = k; drawRegions(); loadMotion(); }; box.appendChild(b);
  };
  add("Whole frame", -1);
  S.regions.forEach((r, k) => add(`R${k + 1} ${r.join(",")}`, k));
  if (S.mask) {
    add("Mask", MASK);
    const b = document.createElement("button"); b.textContent = "Clear mask";
    b.onclick = () => { S.mask = null; if (S.sel === MASK) S.sel = -1; drawRegions(); loadMotion(); }; box.appendChild(b);
  }
  if (S.regions.length) {
    const b = document.createElement("button"); b.textContent = "Clear regions";
    b.onclick = () => { S.regions = []; S.sel = -1; drawRegions(); loadMotion(); }; box.appendChild(b);
  }
}
function setupRegions() {
  const o = $("overlay");
  let painting = false;
  o.addEventListener("mousedown", (ev) => {
    if (!S.info || IDV.on) return;
    if (S.painting) { painting = true; paintAt(ev); } else drag = { a: framePoint(ev), b: framePoint(ev) };
  });
  o.addEventListener("mousemove", (ev) => {
    if (painting) paintAt(ev);
    else if (drag) { drag.b = framePoint(ev); drawRegions(); }
  });
  window.addEventListener("mouseup", (ev) => {
    if (painting) { painting = false; S.sel = MASK; drawRegions(); loadMotion(); return; }
    if (!drag) return;
    drag.b = framePoint(ev);
    const r = dragRoi(); drag = null;
    if (r[2] >= 8 && r[3] >= 8) { S.regions.push(r); S.sel = S.regions.length - 1; drawRegions(); loadMotion(); }
    else drawRegions();
  });
}

// ---- waveform, spectrum, peaks ----
async function loadMotion() {
  if (!S.video) return;
  const sel = selection(), roi = sel.roi;
  const title = () => sel.mask ? "Mask" : roi ? `Region R${S.sel + 1} (${roi.join(",")})` : "Whole frame";
  $("plottitle").textContent = title() + ": computing…";
  const body = { video: S.video, roi };
  if (sel.mask) body.mask = sel.mask;
  if (S.fps) body.fps = S.fps;
  const scale = scaleParam();
  if (scale === undefined) { $("plottitle").textContent = "Error"; return false; }
  if (scale !== null) body.scale_mm_per_px = scale;
  try {
    const m = await (await api("/api/motion", null, body)).json();
    S.motion = m; S.motionSeq++;
    S.damp = null; $("damppanel").hidden = true;
    clearError();
    $("plottitle").textContent = title() + (m.mask_pixels ? ` (${m.mask_pixels} px, in ${m.roi.join(",")})` : "") +
      ` — ${m.peaks.length} resonances, resolution ${m.resolution_hz.toFixed(3)} Hz` + (m.cached ? " (cached)" : "");
    drawWaveform(); drawSpectrum(); fillPeaks();
    return true;
  } catch (e) { $("plottitle").textContent = "Error"; showError(e.message); return false; }
}

function axes(g, c, L, B, xlabel, ylabel) {
  g.fillStyle = "#0e1014"; g.fillRect(0, 0, c.width, c.height);
  g.strokeStyle = "#555"; g.strokeRect(L, 8, c.width - L - 10, c.height - B - 8);
  g.fillStyle = "#aaa"; g.font = "11px sans-serif";
  g.fillText(xlabel, c.width - 10 - g.measureText(xlabel).width, c.height - 4);
  g.save(); g.translate(11, 8 + (c.height - B) / 2); g.rotate(-Math.PI / 2); g.fillText(ylabel, -20, 0); g.restore();
}

function drawWaveform() {
  const c = $("waveform"), g = c.getContext("2d"), m = S.motion.waveform;
  const L = 50, B = 22, W = c.width - L - 10, H = c.height - B - 8;
  axes(g, c, L, B, "time (s)", m.unit);
  const n = m.y.length; if (!n) return;
  let lo = Infinity, hi = -Infinity;
  for (const a of [m.x, m.y]) for (const v of a) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (hi <= lo) { hi = lo + 1e-3; }
  const t0 = m.t_s[0], t1 = m.t_s[n - 1] || t0 + 1;
  const X = (t) => L + (t - t0) / (t1 - t0 || 1) * W, Y = (v) => 8 + (hi - v) / (hi - lo) * H;
  for (const [a, col] of [[m.x, "#77aaff"], [m.y, "#ffaa55"]]) {
    g.strokeStyle = col; g.beginPath();
    for (let k = 0; k < n; k++) { const x = X(m.t_s[k]), y = Y(a[k]); k ? g.lineTo(x, y) : g.moveTo(x, y); }
    g.stroke();
  }
  g.fillStyle = "#aaa";
  g.fillText(hi.toPrecision(3), 2, 16); g.fillText(lo.toPrecision(3), 2, 8 + H);
  g.fillText(t0.toFixed(2), L, c.height - 4); g.fillText(t1.toFixed(2) + " s", L + W - 30, 8 + H + 12);
  g.fillStyle = "#77aaff"; g.fillText("x", L + 6, 20); g.fillStyle = "#ffaa55"; g.fillText("y", L + 18, 20);
}

const SPEC = { L: 50, R: 10, T: 8, B: 22 };
function nyquist() { return S.motion.sample_rate_hz / 2; }
// Canvas x (pixels from the canvas's left edge) of frequency f, for the test.
S.freqToX = (f) => { const c = $("spectrum"); return SPEC.L + f / nyquist() * (c.width - SPEC.L - SPEC.R); };
function xToFreq(x) { const c = $("spectrum"); return (x - SPEC.L) / (c.width - SPEC.L - SPEC.R) * nyquist(); }

function drawSpectrum() {
  const c = $("spectrum"), g = c.getContext("2d"), sp = S.motion.spectrum;
  axes(g, c, SPEC.L, SPEC.B, "frequency (Hz)", "power (dB)");
  if (!sp) return;
  const p = sp.power_db, H = c.height - SPEC.B - SPEC.T;
  let lo = Infinity, hi = -Infinity;
  for (const v of p) if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  lo = Math.max(lo, hi - 80);
  const Y = (v) => SPEC.T + (hi - Math.max(v, lo)) / (hi - lo || 1) * H;
  g.strokeStyle = "#66dd88"; g.beginPath();
  p.forEach((v, k) => { const x = S.freqToX(sp.f0_hz + k * sp.resolution_hz), y = Y(v); k ? g.lineTo(x, y) : g.moveTo(x, y); });
  g.stroke();
  g.fillStyle = "#aaa";
  g.fillText(hi.toFixed(0), 4, SPEC.T + 10); g.fillText(lo.toFixed(0), 4, SPEC.T + H);
  const ny = nyquist();
  for (let k = 0; k <= 5; k++) { const f = ny * k / 5; g.fillText(f.toFixed(0), S.freqToX(f) - 8, c.height - 8); }
  g.fillStyle = "#ff5555";
  S.motion.peaks.forEach((pk, k) => { const x = S.freqToX(pk.frequency_hz); g.fillRect(x - 1, SPEC.T, 2, 6); g.fillText(String(k + 1), x + 2, SPEC.T + 12); });
  if (S.mode) { g.strokeStyle = "#ffcc33"; const x = S.freqToX(S.mode.freq_hz); g.beginPath(); g.moveTo(x, SPEC.T); g.lineTo(x, SPEC.T + H); g.stroke(); }
  // The range being dragged, or the damping view's.
  const range = S.specDrag ? [xToFreq(S.specDrag.a), xToFreq(S.specDrag.b)] : S.damp ? [S.damp.damping.lo_hz, S.damp.damping.hi_hz] : null;
  if (range) {
    const a = S.freqToX(Math.min(...range)), b = S.freqToX(Math.max(...range));
    g.fillStyle = "rgba(255, 160, 60, 0.22)"; g.fillRect(a, SPEC.T, b - a, H);
  }
}

// An uncertainty, or where it is unknown (JSON null for NaN) the bound
// `unknown` says in its place: never "n/a" (issue 51).
function plusMinus(v, digits, unknown) {
  return v == null || !Number.isFinite(v) ? unknown : v.toFixed(digits);
}

function fillPeaks() {
  const tb = document.querySelector("#peaks tbody"); tb.innerHTML = "";
  $("ampunit").textContent = `amplitude (${S.motion.amplitude_unit})`;
  S.motion.peaks.forEach((p) => {
    const tr = document.createElement("tr");
    // A peak narrower than the bins gives only an upper bound on damping.
    const bound = p.damping_method.startsWith("resolution_limit");
    const cells = [p.frequency_hz.toFixed(3), plusMinus(p.frequency_std_hz, 3, "≤ ½ bin"),
      (bound ? "≤ " : "") + p.damping_ratio.toFixed(4), bound ? "–" : plusMinus(p.damping_ratio_std, 4, `≤ ${p.damping_ratio.toFixed(4)}`),
      p.prominence_db.toFixed(1), p.false_alarm == null ? "–" : p.false_alarm < 1e-12 ? "< 1e-12" : p.false_alarm.toExponential(1), p.amplitude.toPrecision(3)];
    tr.innerHTML = cells.map((v) => `<td>${v}</td>`).join("");
    tr.title = `show the modal image at ${p.frequency_hz.toFixed(3)} Hz (damping: ${p.damping_method})`;
    tr.onclick = () => showMode(p.frequency_hz);
    if (S.mode && Math.abs(S.mode.freq_hz - p.frequency_hz) < 1e-9) tr.className = "sel";
    tb.appendChild(tr);
  });
  // Peaks the resonance test turned away, apart and unranked, with why.
  const others = S.motion.others || [];
  $("others").textContent = others.length
    ? "Not resonances: " + others.map((p) => `${p.frequency_hz.toFixed(3)} Hz (${p.class}: ${p.class_reason})`).join("; ")
    : "";
}

// ---- modal image ----
async function showMode(f) {
  const body = { video: S.video, freq_hz: f };
  if (S.fps) body.fps = S.fps;
  const scale = scaleParam();
  if (scale === undefined) return;
  if (scale !== null) body.scale_mm_per_px = scale;
  status(`modal image at ${f.toFixed(3)} Hz…`);
  try {
    const m = await (await api("/api/mode", null, body)).json();
    const img = new Image();
    await new Promise((ok, fail) => { img.onload = ok; img.onerror = () => fail(new Error("modal image PNG did not decode")); img.src = m.png; });
    const c = $("modal"), g = c.getContext("2d");
    g.clearRect(0, 0, c.width, c.height); g.drawImage(img, 0, 0);
    c.hidden = false; c.style.opacity = $("opacity").value;
    S.mode = m; S.modeSeq++;
    clearError();
    $("modepanel").hidden = false;
    $("modetitle").textContent = `Modal image at ${f.toFixed(3)} Hz` + (m.cached ? " (cached)" : "") + ` — ${m.elapsed_ms.toFixed(0)} ms`;
    $("amplabel").textContent = `0 … ${m.max_amplitude.toPrecision(3)} ${m.amplitude_unit} (brightness = amplitude)`;
    status(`modal image at ${f.toFixed(3)} Hz`);
    drawSpectrum(); fillPeaks();
  } catch (e) { status(""); showError(e.message); }
}

function hsv(h, s, v) {
  const i = Math.floor(h * 6) % 6, f = h * 6 - Math.floor(h * 6);
  const p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  return [[v, t, p], [q, v, p], [p, v, t], [p, q, v], [t, p, v], [v, p, q]][i];
}
function drawKeys() {
  const w = $("wheel"), g = w.getContext("2d"), im = g.createImageData(w.width, w.height);
  const cx = w.width / 2, cy = w.height / 2, R = cx - 2;
  for (let y = 0; y < w.height; y++) for (let x = 0; x < w.width; x++) {
    const dx = x - cx, dy = cy - y, r = Math.hypot(dx, dy), k = 4 * (y * w.width + x);
    if (r > R) continue;
    const h = ((Math.atan2(dy, dx) / (2 * Math.PI)) + 1) % 1, rgb = hsv(h, 1, r / R);
    im.data[k] = rgb[0] * 255; im.data[k + 1] = rgb[1] * 255; im.data[k + 2] = rgb[2] * 255; im.data[k + 3] = 255;
  }
  g.putImageData(im, 0, 0);
  g.fillStyle = "#fff"; g.font = "10px sans-serif"; g.fillText("0", w.width - 10, cy + 3); g.fillText("π", 2, cy + 3);
  const a = $("ampscale"), ga = a.getContext("2d"), grad = ga.createLinearGradient(0, 0, a.width, 0);
  grad.addColorStop(0, "#000"); grad.addColorStop(1, "#fff"); ga.fillStyle = grad; ga.fillRect(0, 0, a.width, a.height);
}

// The operating deflection shape: the frame warped along y by
// gain x amplitude x cos(phase + θ(t)), θ turning once a second.
function animate(ts) {
  if ($("animate").checked && !IDV.on && S.mode && S.grey && S.mode.width === S.info.width) {
    const c = $("frame"), g = c.getContext("2d"), w = c.width, h = c.height;
    const im = g.createImageData(w, h), gain = +$("gain").value, th = (ts / 1000) * 2 * Math.PI;
    const A = S.mode.amplitude_px, P = S.mode.phase_rad;
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
      const k = y * w + x, d = gain * A[k] * Math.cos(P[k] + th);
      const sy = Math.max(0, Math.min(h - 1, Math.round(y - d)));
      const v = S.grey[sy * w + x], o = 4 * k;
      im.data[o] = im.data[o + 1] = im.data[o + 2] = v; im.data[o + 3] = 255;
    }
    g.putImageData(im, 0, 0);
    S.animating = true;
  } else if (S.animating) {
    S.animating = false; loadFrame(S.frameIndex).catch((e) => showError(e.message));
  }
  requestAnimationFrame(animate);
}

// ---- the damping view (thesis 5.4.2): drag over a spike ----
async function showDamping(lo, hi) {
  const sel = selection(), roi = sel.roi;
  const body = { video: S.video, roi, lo_hz: lo, hi_hz: hi };
  if (sel.mask) body.mask = sel.mask;
  if (S.fps) body.fps = S.fps;
  status(`fitting ${lo.toFixed(2)}–${hi.toFixed(2)} Hz…`);
  try {
    const r = await (await api("/api/damping", null, body)).json();
    S.damp = r; S.dampSeq++;
    clearError();
    const d = r.damping, f = d.fit, fmt = (x, n) => x.toFixed(n);
    $("damppanel").hidden = false;
    $("damptitle").textContent = `Damping over ${fmt(d.lo_hz, 2)}–${fmt(d.hi_hz, 2)} Hz` +
      (sel.mask ? " (the mask)" : roi ? ` (region ${roi.join(",")})` : " (whole frame)");
    $("damptext").textContent = f
      ? `Lorentzian least squares over ${d.bins} bins (${d.taper} taper): f₀ = ${fmt(f.f0_hz, 3)} ± ${fmt(f.f0_std_hz, 3)} Hz, ` +
        `damping ζ = ${f.resolved ? "" : "≤ "}${f.damping_ratio.toFixed(4)} ± ${plusMinus(f.damping_ratio_std, 4, "at most itself")}` +
        ` (half width γ = ${f.gamma_hz.toFixed(3)} Hz${f.resolved ? "" : "; narrower than the bins resolve: an upper bound"})`
      : d.fit_refusal;
    const m = d.ssi;
    $("stabtext").textContent = m
      ? `SSI-cov (orders 2–${d.max_order}, ${d.block_rows} block rows): ζ = ${m.damping_ratio.toFixed(4)} ± ${plusMinus(m.damping_ratio_std, 4, "at most itself (one order)")} at ${fmt(m.frequency_hz, 3)} Hz, ${m.stable_orders} stable orders agree` +
        (d.clusters.length ? `; stable poles cluster at ${d.clusters.map((c) => `${fmt(c.frequency_hz, 2)} Hz (ζ ${c.damping_ratio.toFixed(4)}, ${c.orders} orders)`).join(", ")}` : "")
      : `SSI-cov (orders 2–${d.max_order}, ${d.block_rows} block rows): no stable poles agree in this range` +
        (d.poles.length ? "" : " (the recording is too short for these block rows, or the range holds no pole)");
    drawDampFit(); drawStab(); drawSpectrum();
    status(`damping over ${fmt(d.lo_hz, 2)}–${fmt(d.hi_hz, 2)} Hz`);
  } catch (e) { status(""); showError(e.message); }
}

S.showDamping = showDamping;

// Plot frame for a range [lo, hi] Hz: x maps frequency to canvas pixels.
function rangeAxes(c, lo, hi, ylabel) {
  const g = c.getContext("2d"), L = 50, B = 22;
  axes(g, c, L, B, "frequency (Hz)", ylabel);
  const W = c.width - L - 10, H = c.height - B - 8;
  const X = (f) => L + (f - lo) / (hi - lo) * W;
  g.fillStyle = "#aaa";
  for (let k = 0; k < 4; k++) { const f = lo + (hi - lo) * k / 4; g.fillText(f.toFixed(2), X(f) - 14, c.height - 8); }
  return { g, L, W, H, X };
}

function drawDampFit() {
  const d = S.damp.damping, sp = S.motion.spectrum, f = d.fit;
  const { g, H, X } = rangeAxes($("dampfit"), d.lo_hz, d.hi_hz, "power (dB)");
  const pts = [];
  sp.power_db.forEach((v, k) => { const fr = sp.f0_hz + k * sp.resolution_hz; if (fr >= d.lo_hz && fr <= d.hi_hz) pts.push([fr, v]); });
  let lo = Infinity, hi = -Infinity;
  for (const [, v] of pts) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (f) for (const v of f.curve_db) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (!(hi > lo)) hi = lo + 1;
  const pad = 0.05 * (hi - lo); lo -= pad; hi += pad;
  const Y = (v) => 8 + (hi - v) / (hi - lo) * H;
  g.strokeStyle = "#66dd88"; g.fillStyle = "#66dd88"; g.beginPath();
  pts.forEach(([fr, v], k) => { k ? g.lineTo(X(fr), Y(v)) : g.moveTo(X(fr), Y(v)); });
  g.stroke();
  for (const [fr, v] of pts) g.fillRect(X(fr) - 1.5, Y(v) - 1.5, 3, 3);
  if (f) {
    g.strokeStyle = "#ff9933"; g.lineWidth = 2; g.beginPath();
    f.curve_hz.forEach((fr, k) => { const y = Y(f.curve_db[k]); k ? g.lineTo(X(fr), y) : g.moveTo(X(fr), y); });
    g.stroke(); g.lineWidth = 1;
    g.strokeStyle = "#ffcc33"; g.setLineDash([4, 3]); g.beginPath(); g.moveTo(X(f.f0_hz), 8); g.lineTo(X(f.f0_hz), 8 + H); g.stroke(); g.setLineDash([]);
    g.fillStyle = "#ff9933"; g.fillText(`Lorentzian fit: ζ = ${f.damping_ratio.toFixed(4)} ± ${plusMinus(f.damping_ratio_std, 4, "at most itself")}`, 60, 22);
  }
  g.fillStyle = "#66dd88"; g.fillText("spectrum", 60, 36);
  g.fillStyle = "#aaa"; g.fillText(hi.toFixed(0), 4, 18); g.fillText(lo.toFixed(0), 4, 8 + H);
}

function drawStab() {
  const d = S.damp.damping, sp = S.motion.spectrum;
  const { g, H, X } = rangeAxes($("stab"), d.lo_hz, d.hi_hz, "model order");
  const top = d.max_order + 2, Y = (n) => 8 + (1 - n / top) * H;
  // The spectrum, faint, behind the poles.
  const pts = [];
  sp.power_db.forEach((v, k) => { const fr = sp.f0_hz + k * sp.resolution_hz; if (fr >= d.lo_hz && fr <= d.hi_hz) pts.push([fr, v]); });
  if (pts.length) {
    let lo = Infinity, hi = -Infinity;
    for (const [, v] of pts) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    g.strokeStyle = "rgba(102, 221, 136, 0.35)"; g.beginPath();
    pts.forEach(([fr, v], k) => { const y = 8 + (hi - v) / (hi - lo || 1) * H; k ? g.lineTo(X(fr), y) : g.moveTo(X(fr), y); });
    g.stroke();
  }
  for (const p of d.poles) {
    const x = X(p.frequency_hz), y = Y(p.order);
    if (p.stable) { g.fillStyle = "#33cc66"; g.beginPath(); g.arc(x, y, 3.5, 0, 2 * Math.PI); g.fill(); }
    else { g.strokeStyle = "#888"; g.beginPath(); g.moveTo(x - 3, y - 3); g.lineTo(x + 3, y + 3); g.moveTo(x + 3, y - 3); g.lineTo(x - 3, y + 3); g.stroke(); }
  }
  if (d.ssi) { g.strokeStyle = "#ffcc33"; g.setLineDash([4, 3]); g.beginPath(); g.moveTo(X(d.ssi.frequency_hz), 8); g.lineTo(X(d.ssi.frequency_hz), 8 + H); g.stroke(); g.setLineDash([]); }
  g.fillStyle = "#aaa";
  for (let n = 10; n <= d.max_order; n += 10) g.fillText(String(n), 30, Y(n) + 4);
  g.fillStyle = "#33cc66"; g.fillText("● stable", 60, 22); g.fillStyle = "#888"; g.fillText("× not stable", 120, 22);
}

// ---- listening (the listen recipe on the region, played through Web Audio) ----
async function listenRegion() {
  if (!S.video) return showError("open a video first");
  const sel = selection(), roi = sel.roi;
  const body = { video: S.video, roi };
  if (sel.mask) body.mask = sel.mask;
  if (S.fps) body.fps = S.fps;
  // The click starts the audio context (browsers allow sound after a gesture).
  if (!S.audioCtx) S.audioCtx = new AudioContext();
  $("listenstatus").textContent = "recovering the sound…";
  try {
    const r = await (await api("/api/listen", null, body)).json();
    const data = await (await fetch(r.wav)).arrayBuffer();
    const buf = await S.audioCtx.decodeAudioData(data);
    S.sound = r; S.soundBuffer = buf;
    $("audio").src = r.wav;
    drawSoundgram(r.spectrogram);
    if (S.audioCtx.state === "suspended") await S.audioCtx.resume();
    const src = S.audioCtx.createBufferSource();
    src.buffer = buf; src.connect(S.audioCtx.destination); src.start();
    S.soundStarted = true; S.soundSeq++;
    clearError();
    $("listenstatus").textContent = sel.name +
      `: ${r.duration_s.toFixed(2)} s, ${r.sample_rate_hz} Hz, ${r.encoding}` + (r.cached ? " (cached)" : "");
  } catch (e) { $("listenstatus").textContent = ""; showError(e.message); }
}

function drawSoundgram(sg) {
  const c = $("soundgram"), g = c.getContext("2d");
  c.hidden = false;
  g.fillStyle = "#0e1014"; g.fillRect(0, 0, c.width, c.height);
  const cols = sg.db, n = cols.length; if (!n) return;
  let hi = -Infinity;
  for (const col of cols) for (const v of col) hi = Math.max(hi, v);
  const lo = hi - 60, bins = cols[0].length, w = c.width / n, h = c.height / bins;
  cols.forEach((col, k) => col.forEach((v, b) => {
    const t = Math.max(0, Math.min(1, (v - lo) / (hi - lo)));
    g.fillStyle = `hsl(${240 - 240 * t}, 90%, ${10 + 50 * t}%)`;
    g.fillRect(k * w, c.height - (b + 1) * h, Math.ceil(w), Math.ceil(h));
  }));
  g.fillStyle = "#ddd"; g.font = "11px sans-serif";
  g.fillText(`${sg.top_hz.toFixed(0)} Hz`, 4, 12); g.fillText("0 Hz", 4, c.height - 4);
}

// ---- export ----
function download(name, href) { const a = document.createElement("a"); a.href = href; a.download = name; a.click(); }
function downloadText(name, text, mime) { download(name, URL.createObjectURL(new Blob([text], { type: mime }))); }
function base() { return (S.video || "studio").replace(/[^A-Za-z0-9_.-]+/g, "_"); }
function setupExport() {
  $("export-wave-png").onclick = () => download(base() + "-waveform.png", $("waveform").toDataURL("image/png"));
  $("export-spec-png").onclick = () => download(base() + "-spectrum.png", $("spectrum").toDataURL("image/png"));
  $("export-csv").onclick = () => {
    if (!S.motion || !S.motion.spectrum) return showError("nothing to export yet");
    const sp = S.motion.spectrum;
    downloadText(base() + "-spectrum.csv", "frequency_hz,power_db\n" + sp.power_db.map((v, k) => `${sp.f0_hz + k * sp.resolution_hz},${v}`).join("\n") + "\n", "text/csv");
  };
  $("export-json").onclick = () => { if (S.motion) downloadText(base() + "-motion.json", JSON.stringify(S.motion), "application/json"); };
  $("export-wav").onclick = () => {
    if (!S.sound) return showError("press Listen first");
    download(base() + (S.sound.roi ? `-R${S.sound.roi.join("_")}` : "") + ".wav", S.sound.wav);
  };
  $("export-damp-png").onclick = () => { if (S.damp) download(base() + "-damping.png", $("dampfit").toDataURL("image/png")); };
  $("export-stab-png").onclick = () => { if (S.damp) download(base() + "-stabilisation.png", $("stab").toDataURL("image/png")); };
  $("export-damp-json").onclick = () => { if (S.damp) downloadText(base() + "-damping.json", JSON.stringify(S.damp), "application/json"); };
  $("export-damp-csv").onclick = () => {
    const f = S.damp && S.damp.damping.fit;
    if (!f) return showError("no fit to export");
    downloadText(base() + "-damping-fit.csv", "frequency_hz,model_power_db\n" + f.curve_hz.map((x, k) => `${x},${f.curve_db[k]}`).join("\n") + "\n", "text/csv");
  };
  $("export-mode-png").onclick = () => { if (S.mode) download(base() + `-mode-${S.mode.freq_hz.toFixed(2)}Hz.png`, S.mode.png); };
  $("export-mode-json").onclick = () => {
    if (!S.mode) return;
    const { png, ...rest } = S.mode;
    downloadText(base() + `-mode-${S.mode.freq_hz.toFixed(2)}Hz.json`, JSON.stringify(rest), "application/json");
  };
}


// ---- the live view (a pipeline run by the studio) ----
// Each update comes over a WebSocket; the server sends only the latest, so
// a slow page sees fewer updates, never old ones. Counters for the test.
const LIVE = {
  updates: 0, spectra: 0, specSeq: 0, firstMs: null, lastMs: null,
  closed: 0, last: null, frameSeq: 0, frameBusy: false, framesShown: 0, hiDb: null,
  ny: null, mode: null, modeSeq: 0,
  // The magnified view: frames drawn, the last one's number, the arrival
  // times of the last ones (for the rate shown), the frame it holds.
  magShown: 0, magImg: null, magDropped0: null, magFrame: null, magTimes: [], magLast: null, magGaps: 0,
};
S.live = LIVE;

// The Monitor panel (--monitor): each source's state and resonances, and
// the latest events, from GET /api/monitor once a second.
function monitorDetail(e) {
  const f = (x, d) => (typeof x === "number" ? x.toFixed(d) : "");
  switch (e.event) {
    case "alarm": return f(e.observed_hz, 2) + " Hz against " + f(e.frequency_hz, 3) + " ± " + f(e.sigma_hz, 3) + " (z " + f(e.z, 1) + ")";
    case "lost": return "no peak near " + f(e.frequency_hz, 2) + " Hz since t = " + f(e.since_s, 1) + " s";
    case "cleared": return f(e.observed_hz, 2) + " Hz, back within the history";
    case "track": return f(e.frequency_hz, 3) + " ± " + f(e.sigma_hz, 3) + " Hz, ζ " + f(e.damping_ratio, 4);
    case "stale": return "silent " + f(e.silent_s, 1) + " s";
    case "refused": return (e.reason || "") + ": " + (e.message || "");
    case "baseline": return (e.tracks ?? "") + " resonances found";
    case "ended": return (e.items ?? "") + " items";
    default: return "";
  }
}
function cell(tr, text, cls) { const td = document.createElement("td"); td.textContent = text; if (cls) td.className = cls; tr.appendChild(td); }
async function pollMonitor() {
  try {
    const m = await (await api("/api/monitor")).json();
    $("monitorinfo").textContent = "from " + m.endpoints.join(", ") + " (" + m.key + "): " + m.received + " events";
    const sb = $("monsources").tBodies[0]; sb.replaceChildren();
    for (const [src, s] of Object.entries(m.sources)) {
      const tr = document.createElement("tr");
      cell(tr, src); cell(tr, s.state, "state-" + s.state);
      const tracks = Object.values(s.tracks || {}).map((t) => (t.alarmed ? "⚠ " : "") + (t.frequency_hz ?? 0).toFixed(2) + " ± " + (t.sigma_hz ?? 0).toFixed(3));
      cell(tr, tracks.join(", "));
      cell(tr, s.last ? s.last.event + " " + monitorDetail(s.last) : "");
      sb.appendChild(tr);
    }
    const eb = $("monevents").tBodies[0]; eb.replaceChildren();
    for (const e of m.events.slice(0, 20)) {
      const tr = document.createElement("tr");
      cell(tr, e.event, "state-" + (e.event === "alarm" || e.event === "lost" ? "alarm" : e.event));
      cell(tr, e.source || ""); cell(tr, e.track ?? ""); cell(tr, typeof e.t_s === "number" ? e.t_s.toFixed(1) : "");
      cell(tr, monitorDetail(e));
      eb.appendChild(tr);
    }
  } catch (e) { showError("monitor: " + e.message); }
  setTimeout(pollMonitor, 1000);
}

function connectLive() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  let ws;
  try { ws = new WebSocket(proto + "//" + location.host + url("/api/live/ws")); }
  catch (e) { showError("live: " + e.message); return; }
  LIVE.ws = ws;
  ws.binaryType = "arraybuffer";
  ws.onopen = () => { if (LIVE.closed) clearError(); };
  ws.onmessage = (ev) => {
    if (ev.data instanceof ArrayBuffer) { drawMagnified(ev.data); return; }
    let u;
    try { u = JSON.parse(ev.data); } catch (_) { showError("live: an update that is not JSON"); return; }
    onLive(u);
  };
  ws.onclose = () => {
    LIVE.closed++;
    if (LIVE.last && LIVE.last.state !== "running") return; // the pipeline ended: nothing more comes
    showError("the live connection was lost; reconnecting…");
    setTimeout(connectLive, 1000);
  };
}

function onLive(u) {
  LIVE.updates++; LIVE.last = u;
  const sp = u.spectrum;
  if (sp && sp.seq !== LIVE.specSeq) {
    const now = performance.now();
    LIVE.specSeq = sp.seq; LIVE.spectra++;
    if (LIVE.firstMs === null) LIVE.firstMs = now;
    LIVE.lastMs = now;
    drawLiveSpectrum(sp); pushSpectrogram(sp); fillLivePeaks(sp);
    const hop = LIVE.prevT != null ? sp.t_s - LIVE.prevT : null;
    LIVE.prevT = sp.t_s;
    if (hop > 0) {
      $("gramcaption").textContent = `spectrogram: 0 Hz at the bottom, ${(sp.rate_hz / 2).toFixed(0)} Hz at the top, ` +
        `newest on the right, ${($("spectrogram").width / 2 * hop).toFixed(1)} s across; colour over the top 60 dB`;
    }
  }
  if (u.level) drawLevel(u.level);
  if (u.frame && u.frame.seq !== LIVE.frameSeq && !LIVE.frameBusy) loadLiveFrame(u.frame);
  fillLiveStats(u);
  fillMagnifyInfo(u);
  const age = sp && sp.age_ms != null ? `, newest sample ${sp.age_ms.toFixed(0)} ms old` : "";
  $("livetitle").textContent = `Live: ${u.pipeline} — ${u.state}` +
    (u.now_s != null ? ` at ${u.now_s.toFixed(1)} s` : "") + (sp ? ` — spectrum ${sp.seq}${age}` : "");
  if (u.state === "failed") showError(u.message || "the live pipeline failed");
  else if (u.state === "finished") status(u.message || "the live pipeline ended");
}

// A magnified frame from the WebSocket: "VMAG", width, height (u32),
// frame number (u64), capture time (i64 ns), then 8-bit grey pixels.
function drawMagnified(buf) {
  const d = new DataView(buf);
  if (buf.byteLength < 28 || d.getUint32(0, false) !== 0x564d4147) return showError("live: a binary message that is not a magnified frame");
  const w = d.getUint32(4, true), h = d.getUint32(8, true);
  const frame = Number(d.getBigUint64(12, true)), t = Number(d.getBigInt64(20, true)) * 1e-9;
  const px = new Uint8Array(buf, 28);
  if (px.length !== w * h) return showError(`live: a magnified frame of ${px.length} bytes for ${w}x${h}`);
  const c = $("livemag");
  if (c.width !== w || c.height !== h) { c.width = w; c.height = h; c.style.width = Math.min(w, 1280) + "px"; }
  // One ImageData kept while the size holds (no 1.2 MB allocation a frame
  // at 640x480 side by side), filled a pixel a store: grey v is RGBA
  // (v, v, v, 255), little-endian 0xff000000 | v * 0x010101.
  const g = c.getContext("2d");
  if (!LIVE.magImg || LIVE.magImg.width !== w || LIVE.magImg.height !== h) LIVE.magImg = g.createImageData(w, h);
  const img = LIVE.magImg, o = new Uint32Array(img.data.buffer);
  for (let i = 0; i < px.length; i++) o[i] = 0xff000000 | (px[i] * 0x010101);
  g.putImageData(img, 0, 0);
  if (LIVE.magFrame === null) LIVE.magDropped0 = magDropped(LIVE.last);
  if (LIVE.magFrame !== null && frame > LIVE.magFrame + 1) LIVE.magGaps += frame - LIVE.magFrame - 1;
  LIVE.magShown++; LIVE.magFrame = frame; LIVE.magLast = { frame, t_s: t, width: w, height: h };
  const now = performance.now();
  LIVE.magTimes.push(now);
  while (LIVE.magTimes.length > 2 && now - LIVE.magTimes[0] > 2000) LIVE.magTimes.shift();
  $("livemagbox").hidden = false;
}

// The magnify stage's drops (its input ring's) in an update, 0 before any.
function magDropped(u) {
  const st = u && u.magnify && u.stages ? u.stages.find((s) => s.id === u.magnify.stage) : null;
  return st ? st.dropped : 0;
}

// The magnified view's line: rate on the page, frames not shown, drops.
function fillMagnifyInfo(u) {
  const m = u.magnify; if (!m) return;
  const ts = LIVE.magTimes, n = ts.length;
  const fps = n > 1 ? (n - 1) / ((ts[n - 1] - ts[0]) / 1e3) : 0;
  const dropped = magDropped(u);
  // The frame numbers the page skipped, less those the magnifier never
  // got (dropped before it since the page's first frame): what the
  // server did not send because the page was slower.
  const missed = LIVE.magDropped0 === null ? 0 : Math.max(0, LIVE.magGaps - (dropped - LIVE.magDropped0));
  $("livemaginfo").textContent = `magnified ${m.lo_hz}–${m.hi_hz} Hz ×${m.factor}` +
    (m.since_frame != null ? ` since frame ${m.since_frame}` : "") +
    ` — ${LIVE.magShown} frames shown, ${fps.toFixed(1)} a second` +
    (LIVE.magFrame != null ? ` (frame ${LIVE.magFrame})` : "") +
    `; not shown (the page was slower) ${missed}; dropped before the magnifier (it was slower) ${dropped}` +
    (m.refused ? `; last change refused: ${m.refused}` : "") + (m.pending ? "; change waiting for a frame" : "");
  const set = (id, v) => { const e = $(id); if (document.activeElement !== e && !LIVE.magEdited) e.value = v; };
  set("maglo", m.lo_hz); set("maghi", m.hi_hz); set("magfactor", m.factor);
  LIVE.magInfo = { fps, dropped, gaps: LIVE.magGaps, missed, shown: LIVE.magShown };
}

async function applyMagnify() {
  const lo = parseFloat($("maglo").value), hi = parseFloat($("maghi").value), factor = parseFloat($("magfactor").value);
  if (![lo, hi, factor].every(Number.isFinite)) return showError("the band and factor must be numbers");
  try {
    const r = await (await api("/api/live/magnify", null, { lo_hz: lo, hi_hz: hi, factor })).json();
    LIVE.magEdited = false; clearError();
    LIVE.magApplied = r;
    status(r.pending ? "the change waits for the next frame" : `magnifying ${lo}–${hi} Hz ×${factor} from frame ${r.since_frame}`);
  } catch (e) { showError(e.message); }
}

function loadLiveFrame(f) {
  LIVE.frameBusy = true;
  const img = $("liveframe");
  const done = () => { LIVE.frameBusy = false; };
  img.onload = () => { LIVE.frameSeq = f.seq; LIVE.framesShown++; done(); };
  img.onerror = done;
  const sc = Math.max(1, Math.min(4, Math.floor(320 / f.width)));
  img.width = f.width * sc; img.height = f.height * sc;
  img.src = url("/api/live/frame", { n: f.seq });
  img.title = `frame ${f.frame} at ${f.t_s.toFixed(3)} s`;
}

const LSPEC = { L: 50, R: 10, T: 8, B: 22 };
function drawLiveSpectrum(sp) {
  const c = $("livespec"), g = c.getContext("2d");
  axes(g, c, LSPEC.L, LSPEC.B, "frequency (Hz)", "power (dB)");
  const p = sp.db, H = c.height - LSPEC.B - LSPEC.T, W = c.width - LSPEC.L - LSPEC.R;
  let hi = -Infinity;
  for (const v of p) if (isFinite(v)) hi = Math.max(hi, v);
  LIVE.hiDb = LIVE.hiDb === null ? hi : Math.max(hi, LIVE.hiDb - 0.5); // slow fall, fast rise
  const top = LIVE.hiDb + 3, lo = top - 70;
  const ny = sp.rate_hz / 2;
  LIVE.ny = ny;
  const X = (f) => LSPEC.L + f / ny * W, Y = (v) => LSPEC.T + (top - Math.max(v, lo)) / (top - lo) * H;
  g.strokeStyle = "#66dd88"; g.beginPath();
  p.forEach((v, k) => { const x = X(sp.f0_hz + k * sp.bin_hz), y = Y(v); k ? g.lineTo(x, y) : g.moveTo(x, y); });
  g.stroke();
  g.fillStyle = "#aaa";
  g.fillText(top.toFixed(0), 4, LSPEC.T + 10); g.fillText(lo.toFixed(0), 4, LSPEC.T + H);
  for (let k = 0; k <= 5; k++) { const f = ny * k / 5; g.fillText(f.toFixed(0), X(f) - 8, c.height - 8); }
  g.fillStyle = "#ff5555";
  sp.peaks.forEach((pk, k) => { const x = X(pk.frequency_hz); g.fillRect(x - 1, LSPEC.T, 2, 6); g.fillText(`${k + 1}: ${pk.frequency_hz.toFixed(1)}`, x + 3, LSPEC.T + 12 + 12 * k); });
  if (LIVE.mode) { g.strokeStyle = "#ffcc33"; const x = X(LIVE.mode.freq_hz); g.beginPath(); g.moveTo(x, LSPEC.T); g.lineTo(x, LSPEC.T + H); g.stroke(); }
}
// Canvas x of frequency f on the live spectrum, for the test.
LIVE.freqToX = (f) => { const c = $("livespec"); return LSPEC.L + f / LIVE.ny * (c.width - LSPEC.L - LSPEC.R); };

// The modal image at f from the live pipeline's last seconds of frames.
async function showLiveMode(f) {
  $("livemodetitle").textContent = `modal image at ${f.toFixed(2)} Hz from the last frames…`;
  $("livemodebox").hidden = false;
  try {
    const m = await (await api("/api/live/mode", null, { freq_hz: f })).json();
    const img = new Image();
    await new Promise((ok, fail) => { img.onload = ok; img.onerror = () => fail(new Error("modal image PNG did not decode")); img.src = m.png; });
    const c = $("livemode"), g = c.getContext("2d"), sc = Math.max(1, Math.min(4, Math.floor(320 / m.width)));
    c.width = m.width; c.height = m.height; c.style.width = m.width * sc + "px"; c.style.height = m.height * sc + "px";
    g.drawImage(img, 0, 0);
    LIVE.mode = m; LIVE.modeSeq++;
    clearError();
    $("livemodetitle").textContent = `Modal image at ${m.freq_hz.toFixed(2)} Hz from the last ${m.frames} frames ` +
      `(${m.span_s.toFixed(2)} s at ${m.fps.toFixed(1)} fps; ${m.elapsed_ms.toFixed(0)} ms): hue = phase, brightness = amplitude, 0 … ${m.max_amplitude_px.toPrecision(3)} px`;
  } catch (e) { $("livemodetitle").textContent = ""; showError(e.message); }
}
S.showLiveMode = showLiveMode;

function pushSpectrogram(sp) {
  const c = $("spectrogram"), g = c.getContext("2d"), col = 2;
  g.drawImage(c, -col, 0);
  const top = (LIVE.hiDb ?? 0) + 3, lo = top - 60, n = sp.db.length;
  for (let y = 0; y < c.height; y++) {
    const k = Math.min(n - 1, Math.floor((c.height - 1 - y) / c.height * n));
    const t = Math.max(0, Math.min(1, (sp.db[k] - lo) / (top - lo)));
    g.fillStyle = `hsl(${240 - 240 * t}, 90%, ${10 + 50 * t}%)`;
    g.fillRect(c.width - col, y, col, 1);
  }
}

function drawLevel(l) {
  const c = $("level"), g = c.getContext("2d");
  g.fillStyle = "#0e1014"; g.fillRect(0, 0, c.width, c.height);
  LIVE.levelHi = LIVE.levelHi == null ? l.db : Math.max(l.db, LIVE.levelHi - 0.2);
  const top = LIVE.levelHi + 6, lo = top - 60;
  const t = Math.max(0, Math.min(1, (l.db - lo) / (top - lo)));
  g.fillStyle = t > 0.9 ? "#ff5555" : "#66dd88";
  g.fillRect(6, c.height * (1 - t), c.width - 12, c.height * t);
  $("leveltext").textContent = `${l.db.toFixed(1)} dB`;
}

function fillLivePeaks(sp) {
  const tb = document.querySelector("#livepeaks tbody"); tb.innerHTML = "";
  for (const p of sp.peaks) {
    const tr = document.createElement("tr");
    tr.title = `the modal image at ${p.frequency_hz.toFixed(2)} Hz from the last seconds of frames`;
    tr.onclick = () => showLiveMode(p.frequency_hz);
    for (const v of [p.frequency_hz.toFixed(2), plusMinus(p.frequency_std_hz, 2, "≤ ½ bin"), p.prominence_db.toFixed(1),
      p.damping_ratio.toExponential(2)]) {
      const td = document.createElement("td"); td.textContent = v; tr.appendChild(td);
    }
    tb.appendChild(tr);
  }
}

function fillLiveStats(u) {
  const tb = document.querySelector("#livestats tbody"); tb.innerHTML = "";
  for (const st of u.stages) {
    const tr = document.createElement("tr");
    for (const v of [st.id, st.kind, st.items_in, st.items_out, st.dropped,
      st.queue_capacity ? `${st.queued}/${st.queue_capacity}` : "-", st.busy_s.toFixed(2)]) {
      const td = document.createElement("td"); td.textContent = String(v); tr.appendChild(td);
    }
    if (st.dropped > 0) tr.className = "sel";
    tb.appendChild(tr);
  }
  const k = u.skipped;
  $("liveinfo").textContent = `updates received ${LIVE.updates}, spectra ${LIVE.spectra}; ` +
    `the taps kept the latest and skipped ${k.spectrum} spectra, ${k.frame} frames, ${k.samples} sample blocks (never waiting)`;
}

function setupLiveExport() {
  $("magapply").onclick = applyMagnify;
  for (const id of ["maglo", "maghi", "magfactor"]) {
    $(id).addEventListener("input", () => { LIVE.magEdited = true; });
    $(id).addEventListener("keydown", (ev) => { if (ev.key === "Enter") applyMagnify(); });
  }
  $("export-live-mag").onclick = () => {
    if (LIVE.magFrame === null) return showError("no magnified frame yet");
    download(`live-magnified-${LIVE.magFrame}.png`, $("livemag").toDataURL("image/png"));
  };
  $("export-live-mode").onclick = () => { if (LIVE.mode) download(`live-mode-${LIVE.mode.freq_hz.toFixed(2)}Hz.png`, LIVE.mode.png); };
  $("livespec").addEventListener("click", (ev) => {
    if (!LIVE.ny) return;
    const c = $("livespec"), b = c.getBoundingClientRect(), x = (ev.clientX - b.left) * c.width / b.width;
    let f = (x - LSPEC.L) / (c.width - LSPEC.L - LSPEC.R) * LIVE.ny;
    // Within 6 px of a listed peak: that peak's own frequency (a click's
    // pixel is a fraction of a bin off, and the image is made at exactly
    // the frequency asked).
    const sp = LIVE.last && LIVE.last.spectrum;
    if (sp) for (const pk of sp.peaks) if (Math.abs(LIVE.freqToX(pk.frequency_hz) - x) <= 6) f = pk.frequency_hz;
    if (f > 0 && f <= LIVE.ny) showLiveMode(f);
  });
  const name = () => (LIVE.last ? LIVE.last.pipeline : "live").replace(/[^A-Za-z0-9_.-]+/g, "_");
  $("export-live-png").onclick = () => download(name() + "-spectrum.png", $("livespec").toDataURL("image/png"));
  $("export-live-gram").onclick = () => download(name() + "-spectrogram.png", $("spectrogram").toDataURL("image/png"));
  $("export-live-json").onclick = () => { if (LIVE.last) downloadText(name() + "-update.json", JSON.stringify(LIVE.last), "application/json"); };
  $("export-live-csv").onclick = () => {
    const sp = LIVE.last && LIVE.last.spectrum;
    if (!sp) return showError("no live spectrum yet");
    downloadText(name() + "-spectrum.csv", "frequency_hz,power_db\n" + sp.db.map((v, k) => `${sp.f0_hz + k * sp.bin_hz},${v}`).join("\n") + "\n", "text/csv");
  };
}

// ---- interactive dynamic video (thesis ch. 6): drag the object ----
// The server measures the region's image-space modal basis (/api/idv/basis);
// the page simulates each mode as a damped oscillator and renders
// D = Σ Re{φ'_i q_i} (Eq. 6.10) warped onto the rest frame with the depth
// rule, as the library's math::idv::Renderer does. Buffers are made once
// per basis; a frame allocates nothing.
const IDV = { engine: null, basis: null, on: false, seq: 0, grabs: 0, releases: 0,
  frames: 0, fps: 0, lastTs: null, fpsT0: null, fpsN: 0, refused: 0 };
S.idv = IDV;
const LITTLE_ENDIAN = new Uint8Array(new Uint32Array([1]).buffer)[0] === 1;
function b64bytes(s) {
  const bin = atob(s), b = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) b[i] = bin.charCodeAt(i);
  return b;
}
function f32le(bytes) {
  if (LITTLE_ENDIAN) return new Float32Array(bytes.buffer, bytes.byteOffset, bytes.byteLength >> 2);
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength), out = new Float32Array(bytes.byteLength >> 2);
  for (let i = 0; i < out.length; i++) out[i] = dv.getFloat32(4 * i, true);
  return out;
}

// b: {width, height, box: [x, y, w, h], rest: Uint8Array(w*h), modes: [{freq_hz,
// damping_ratio, shape: Float32Array(4 per box pixel: xr, xi, yr, yi)}]}.
function makeIdv(b) {
  const w = b.width, h = b.height, n = w * h, m = b.modes.length, [, , bw, bh] = b.box;
  const E = {
    // The shapes packed per pixel, mode after mode (xr, xi, yr, yi each):
    // Eq. 6.10 then reads one stream and sums each pixel in registers.
    w, h, box: b.box, rest: b.rest, m, ph: new Float32Array(4 * m * bw * bh), q: new Float64Array(2 * m),
    freq: Float64Array.from(b.modes, (md) => md.freq_hz), xi0: Float64Array.from(b.modes, (md) => md.damping_ratio),
    omega: new Float64Array(m), xi: new Float64Array(m), rho: new Float64Array(m), vel: new Float64Array(m),
    dx: new Float32Array(n), dy: new Float32Array(n), depth: new Float32Array(n),
    ownx: new Float32Array(n), owny: new Float32Array(n), image: new ImageData(w, h),
    held: false, grab: -1, p: [0, 0], d: [0, 0], strength: 1, velocity: false, reachMax: 0,
  };
  E.image.data.fill(255);
  b.modes.forEach((md, i) => {
    for (let k = 0; k < bw * bh; k++) for (let c = 0; c < 4; c++) E.ph[4 * (k * m + i) + c] = md.shape[4 * k + c];
  });
  // The largest Σ_i |φ'_i|² in the box: a point far below it barely moves.
  for (let k = 0; k < bw * bh; k++) E.reachMax = Math.max(E.reachMax, idvReach(E, k));
  idvSetDamping(E, 1);
  return E;
}

// Every ξ times `scale`, then ω as math::idv::Oscillator::new makes it
// (the free motion rings at the measured damped frequency).
function idvSetDamping(E, scale) {
  for (let i = 0; i < E.m; i++) {
    const xi = Math.max(0, Math.min(0.999, E.xi0[i] * scale));
    E.xi[i] = xi; E.omega[i] = 2 * Math.PI * E.freq[i] / Math.sqrt(1 - xi * xi);
  }
}

// Free motion over h seconds: the exact state transition e^{Ah} of
// math::idv::Oscillator::transition, so the motion does not depend on the
// frame rate.
function idvStep(E, h) {
  if (!(h > 0)) return;
  for (let i = 0; i < E.m; i++) {
    const w = E.omega[i], sigma = E.xi[i] * w, wd = w * Math.sqrt(1 - E.xi[i] * E.xi[i]);
    const e = Math.exp(-sigma * h), s = Math.sin(wd * h), c = Math.cos(wd * h);
    const p11 = e * (c + sigma / wd * s), p12 = e * s / wd, p21 = -e * w * w / wd * s, p22 = e * (c - sigma / wd * s);
    const r = E.rho[i], v = E.vel[i];
    E.rho[i] = p11 * r + p12 * v; E.vel[i] = p21 * r + p22 * v;
  }
}

// Σ_i |φ'_i(p)|² at box pixel k: whether the grabbed point moves at all.
function idvReach(E, k) {
  let r = 0;
  for (let j = 4 * k * E.m; j < 4 * (k + 1) * E.m; j++) r += E.ph[j] * E.ph[j];
  return r;
}

// Direct manipulation (Eq. 6.7-6.8, math::idv::manipulate): with a_i =
// dᵀφ'_i(p), |q_i| = |a_i| α and Arg q_i = -Arg a_i, i.e. q_i = α conj(a_i),
// which maximises the displacement of p along d. α = strength /
// Σ_i |d̂ᵀφ'_i(p)|² makes p move by strength x |d| along d (the sum is
// floored at a quarter of Σ_i |φ'_i(p)|², so a drag across the
// direction the point can move moves it little instead of without bound).
// "Throw" (Eq. 6.9) turns the phase by a quarter period so that p sits
// at rest and moves along d when let go (with q = ρ - iρ'/ω the free
// motion turns q by e^{+iωt}, so the turn is -π/2).
function idvHold(E) {
  const k = E.grab, len = Math.hypot(E.d[0], E.d[1]);
  if (k < 0) return;
  if (len === 0) { E.rho.fill(0); E.vel.fill(0); return; }
  const ux = E.d[0] / len, uy = E.d[1] / len;
  let along = 0;
  const s = E.ph;
  for (let i = 0, j = 4 * k * E.m; i < E.m; i++, j += 4) {
    const ar = ux * s[j] + uy * s[j + 2], ai = ux * s[j + 1] + uy * s[j + 3];
    along += ar * ar + ai * ai;
  }
  const all = idvReach(E, k);
  if (!(all > 0)) return;
  const alpha = E.strength / Math.max(along, 0.25 * all);
  for (let i = 0, j = 4 * k * E.m; i < E.m; i++, j += 4) {
    const ar = E.d[0] * s[j] + E.d[1] * s[j + 2], ai = E.d[0] * s[j + 1] + E.d[1] * s[j + 3];
    let qr = alpha * ar, qi = -alpha * ai;
    if (E.velocity) { const t = qr; qr = -qi; qi = -t; } // q x (-i)
    // math::idv::Oscillator::set_q: ρ = Re q, ρ' = -ω Im q.
    E.rho[i] = qr; E.vel[i] = -qi * E.omega[i];
  }
}

// Eq. 6.10 then the forward warp with the depth rule (math::idv::Renderer):
// every pixel lands on the output pixel nearest to where it moves, the
// one moving most wins, each output pixel samples the rest frame
// bilinearly at itself minus the winner's displacement; a pixel nothing
// lands on samples it with its own displacement.
function idvRender(E, g) {
  const { w, h, dx, dy, depth, ownx, owny, rest } = E, data = E.image.data;
  const bx = E.box[0], by = E.box[1], bw = E.box[2], bh = E.box[3];
  const m = E.m, q = E.q, s = E.ph;
  for (let i = 0; i < m; i++) { q[2 * i] = E.rho[i]; q[2 * i + 1] = -E.vel[i] / E.omega[i]; }
  for (let y = 0, k = 0; y < bh; y++) {
    let o = (by + y) * w + bx;
    for (let x = 0; x < bw; x++, o++) {
      let sx = 0, sy = 0;
      for (let i = 0; i < 2 * m; i += 2, k += 4) {
        const qr = q[i], qi = q[i + 1];
        sx += s[k] * qr - s[k + 1] * qi; sy += s[k + 2] * qr - s[k + 3] * qi;
      }
      dx[o] = sx; dy[o] = sy;
    }
  }
  depth.fill(-1); ownx.set(dx); owny.set(dy);
  for (let y = 0, i = 0; y < h; y++) {
    for (let x = 0; x < w; x++, i++) {
      const ddx = dx[i], ddy = dy[i], fx = x + ddx, fy = y + ddy;
      // f32::round (halves away from zero); anything at or below -0.5
      // rounds below 0 and is dropped, so -1 stands for it.
      const tx = fx > -0.5 ? (fx + 0.5) | 0 : -1, ty = fy > -0.5 ? (fy + 0.5) | 0 : -1;
      if (tx < 0 || ty < 0 || tx >= w || ty >= h) continue;
      const t = ty * w + tx, mag = ddx * ddx + ddy * ddy;
      if (mag > depth[t]) { depth[t] = mag; ownx[t] = ddx; owny[t] = ddy; }
    }
  }
  const wm = w - 1, hm = h - 1;
  for (let y = 0, i = 0; y < h; y++) {
    for (let x = 0; x < w; x++, i++) {
      let sx = x - ownx[i], sy = y - owny[i];
      sx = sx < 0 ? 0 : sx > wm ? wm : sx; sy = sy < 0 ? 0 : sy > hm ? hm : sy;
      const x0 = sx | 0, y0 = sy | 0, x1 = x0 < wm ? x0 + 1 : wm, y1 = y0 < hm ? y0 + 1 : hm;
      const fx = sx - x0, fy = sy - y0;
      const a = rest[y0 * w + x0] * (1 - fx) + rest[y0 * w + x1] * fx;
      const b = rest[y1 * w + x0] * (1 - fx) + rest[y1 * w + x1] * fx;
      const v = (a * (1 - fy) + b * fy + 0.5) | 0, o = 4 * i;
      data[o] = v; data[o + 1] = v; data[o + 2] = v;
    }
  }
  g.putImageData(E.image, 0, 0);
}

// The overlay in interaction: the basis's box and the arrow from the
// grabbed point to the pointer.
function idvOverlay() {
  const o = $("overlay"), g = o.getContext("2d"), s = S.scale, E = IDV.engine;
  g.clearRect(0, 0, o.width, o.height);
  if (!E) return;
  const [bx, by, bw, bh] = E.box;
  g.strokeStyle = "rgba(255, 204, 51, 0.5)"; g.setLineDash([4, 3]); g.lineWidth = 1;
  g.strokeRect(bx * s + 0.5, by * s + 0.5, bw * s - 1, bh * s - 1); g.setLineDash([]);
  if (!E.held) return;
  const x0 = (E.p[0] + 0.5) * s, y0 = (E.p[1] + 0.5) * s, x1 = x0 + E.d[0] * s, y1 = y0 + E.d[1] * s;
  g.strokeStyle = g.fillStyle = "#ffcc33"; g.lineWidth = 3;
  g.beginPath(); g.arc(x0, y0, 4, 0, 2 * Math.PI); g.fill();
  const len = Math.hypot(x1 - x0, y1 - y0);
  if (len < 1) return;
  const ux = (x1 - x0) / len, uy = (y1 - y0) / len, head = Math.min(14, len * 0.6);
  g.beginPath(); g.moveTo(x0, y0); g.lineTo(x1 - ux * head * 0.5, y1 - uy * head * 0.5); g.stroke();
  g.beginPath(); g.moveTo(x1, y1);
  g.lineTo(x1 - ux * head - uy * head * 0.5, y1 - uy * head + ux * head * 0.5);
  g.lineTo(x1 - ux * head + uy * head * 0.5, y1 - uy * head - ux * head * 0.5);
  g.closePath(); g.fill(); g.lineWidth = 1;
}

function idvPoint(ev) {
  const b = $("overlay").getBoundingClientRect();
  return [(ev.clientX - b.left) / S.scale - 0.5, (ev.clientY - b.top) / S.scale - 0.5];
}

function idvSetOn(on) {
  IDV.on = on && !!IDV.engine;
  $("idvon").checked = IDV.on;
  $("overlay").style.cursor = IDV.on ? "grab" : "crosshair";
  IDV.lastTs = null; IDV.fpsT0 = null;
  if (IDV.on) idvOverlay();
  else { drawRegions(); if (S.video) loadFrame(S.frameIndex).catch((e) => showError(e.message)); }
}

async function idvLoad() {
  if (!S.video) return showError("open a video first");
  const sel = selection();
  const body = { video: S.video, roi: sel.roi, modes: $("idvmodes").value.trim() || "auto" };
  if (sel.mask) body.mask = sel.mask;
  if (S.fps) body.fps = S.fps;
  $("idvinfo").textContent = `measuring the modal basis of ${sel.name}…`;
  try {
    const r = await (await api("/api/idv/basis", null, body)).json();
    const [, , bw, bh] = r.box;
    const rest = b64bytes(r.rest);
    if (rest.length !== r.width * r.height) throw new Error("the basis's rest frame is not the frame's size");
    const modes = r.modes.map((md) => {
      const shape = f32le(b64bytes(md.shape));
      if (shape.length !== 4 * bw * bh) throw new Error(`mode ${md.freq_hz} Hz: its shape is not the box's size`);
      return { freq_hz: md.freq_hz, damping_ratio: md.damping_ratio, damping_method: md.damping_method, shape };
    });
    IDV.engine = makeIdv({ width: r.width, height: r.height, box: r.box, rest, modes });
    idvApplySliders();
    delete r.rest; r.modes.forEach((md) => { delete md.shape; });
    IDV.basis = r; IDV.seq++;
    clearError();
    $("idvon").disabled = false;
    $("idvinfo").textContent = `${modes.length} modes over ${sel.name} (${r.box.join(",")}): ` +
      r.modes.map((md) => `${md.freq_hz.toFixed(2)} Hz (ζ ${md.damping_ratio.toFixed(3)})`).join(", ") +
      ` — ${(r.payload_bytes / 1e6).toFixed(1)} MB, ${r.elapsed_ms.toFixed(0)} ms${r.cached ? " (cached)" : ""}` +
      (r.notes.length ? "; " + r.notes.join("; ") : "") + ". Drag on the object; let go and it rings.";
    idvSetOn(true);
  } catch (e) { $("idvinfo").textContent = ""; showError(e.message); }
}

function idvApplySliders() {
  const st = +$("idvstrength").value, ds = Math.pow(2, +$("idvdamping").value);
  $("idvstrengthlabel").textContent = st.toFixed(2) + "x";
  $("idvdampinglabel").textContent = "ζ x" + ds.toPrecision(2);
  const E = IDV.engine; if (!E) return;
  E.strength = st; E.velocity = $("idvvelocity").checked; idvSetDamping(E, ds);
}

// One animation frame: the modes held or let go by the real time elapsed.
function idvFrame(ts) {
  const E = IDV.engine;
  if (E && IDV.on && S.info && E.w === S.info.width && E.h === S.info.height) {
    const dt = IDV.lastTs === null ? 0 : (ts - IDV.lastTs) / 1000;
    IDV.lastTs = ts;
    if (E.held) idvHold(E); else idvStep(E, dt);
    idvRender(E, $("frame").getContext("2d"));
    IDV.frames++; IDV.fpsN++;
    if (IDV.fpsT0 === null) { IDV.fpsT0 = ts; IDV.fpsN = 0; }
    else if (ts - IDV.fpsT0 >= 500) {
      IDV.fps = IDV.fpsN * 1000 / (ts - IDV.fpsT0); IDV.fpsT0 = ts; IDV.fpsN = 0;
      $("idvfps").textContent = IDV.fps.toFixed(1);
    }
  }
  requestAnimationFrame(idvFrame);
}

function setupIdv() {
  const o = $("overlay");
  o.addEventListener("pointerdown", (ev) => {
    const E = IDV.engine;
    if (!IDV.on || !E) return;
    ev.preventDefault();
    const [fx, fy] = idvPoint(ev), px = Math.round(fx), py = Math.round(fy), [bx, by, bw, bh] = E.box;
    const inBox = px >= bx && py >= by && px < bx + bw && py < by + bh;
    const k = inBox ? (py - by) * bw + (px - bx) : -1;
    if (k < 0 || idvReach(E, k) < 0.01 * E.reachMax) {
      IDV.refused++;
      $("idvinfo").textContent = `nothing moves at ${px},${py}: grab the object (inside the dashed box, where its modes move)`;
      return;
    }
    E.grab = k; E.p = [px, py]; E.d = [fx - px, fy - py]; E.held = true; IDV.grabs++;
    o.setPointerCapture(ev.pointerId); o.style.cursor = "grabbing";
    idvOverlay();
  });
  o.addEventListener("pointermove", (ev) => {
    const E = IDV.engine;
    if (!IDV.on || !E || !E.held) return;
    const [fx, fy] = idvPoint(ev);
    E.d = [fx - E.p[0], fy - E.p[1]];
    idvOverlay();
  });
  const up = () => {
    const E = IDV.engine;
    if (!E || !E.held) return;
    E.held = false; IDV.releases++;
    o.style.cursor = IDV.on ? "grab" : "crosshair";
    idvOverlay();
  };
  o.addEventListener("pointerup", up);
  o.addEventListener("pointercancel", up);
  $("idvload").onclick = idvLoad;
  $("idvon").onchange = () => idvSetOn($("idvon").checked);
  $("idvrest").onclick = () => { const E = IDV.engine; if (E) { E.rho.fill(0); E.vel.fill(0); } };
  for (const id of ["idvstrength", "idvdamping", "idvvelocity"]) $(id).addEventListener("input", idvApplySliders);
  idvApplySliders();
  requestAnimationFrame(idvFrame);
}

// Renders the current state once into the frame (for the test, which
// reads it back in the same script and compares it with the library's).
S.idvRender = () => { if (IDV.engine) idvRender(IDV.engine, $("frame").getContext("2d")); };

// The frame rate of the page's renderer for a synthetic basis (w x h,
// `modes` smooth modes over the whole frame), drawn to a canvas of its
// own: `frames` frames back to back (simulation + Eq. 6.10 + warp +
// putImageData), then as many as requestAnimationFrame gives in `ms`.
S.idvBench = (w, h, modes, frames, ms) => new Promise((done) => {
  const n = w * h, rest = new Uint8Array(n), md = [];
  for (let i = 0; i < n; i++) rest[i] = ((i % w) >> 3 & 1) ^ ((i / w | 0) >> 3 & 1) ? 200 : 60;
  for (let k = 0; k < modes; k++) {
    const s = new Float32Array(4 * n);
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
      const i = 4 * (y * w + x), u = Math.sin((k + 1) * Math.PI * x / w) * Math.cos(Math.PI * y / h);
      s[i] = 0.3 * u; s[i + 1] = 0.05 * u; s[i + 2] = u; s[i + 3] = 0.1 * u;
    }
    md.push({ freq_hz: 3 + 7 * k, damping_ratio: 0.02, shape: s });
  }
  const E = makeIdv({ width: w, height: h, box: [0, 0, w, h], rest, modes: md });
  const c = document.createElement("canvas"); c.width = w; c.height = h;
  const g = c.getContext("2d");
  E.grab = (h >> 2) * w + (w >> 1); E.d = [0, 10]; idvHold(E);
  const t0 = performance.now();
  for (let f = 0; f < frames; f++) { idvStep(E, 1 / 60); idvRender(E, g); }
  const loopMs = performance.now() - t0;
  let first = null, last = null, count = 0;
  const tick = (ts) => {
    if (first === null) first = ts;
    else { idvStep(E, (ts - last) / 1000); idvRender(E, g); count++; }
    last = ts;
    if (ts - first < ms) requestAnimationFrame(tick);
    else done({ width: w, height: h, modes, frames, loop_ms_per_frame: loopMs / frames,
      loop_fps: frames * 1000 / loopMs, raf_frames: count, raf_fps: count * 1000 / (last - first) });
  };
  requestAnimationFrame(tick);
});

// ---- start ----
async function main() {
  drawKeys(); setupRegions(); setupExport(); setupIdv();
  $("open").onclick = openVideo;
  $("paint").onclick = () => {
    S.painting = !S.painting;
    $("paint").classList.toggle("sel", S.painting);
    $("paint").textContent = S.painting ? "Painting (click to draw rectangles)" : "Paint a mask";
  };
  $("listen").onclick = listenRegion;
  $("video").addEventListener("keydown", (e) => { if (e.key === "Enter") openVideo(); });
  // A new scale: the same answers (cached on the server) in the new unit.
  $("mmpx").addEventListener("change", async () => {
    if (!S.video) return;
    if (await loadMotion() && S.mode) await showMode(S.mode.freq_hz);
  });
  $("scrub").addEventListener("input", () => loadFrame(+$("scrub").value).catch((e) => showError(e.message)));
  // A click shows the modal image there; a drag fits the damping over it.
  const specX = (ev) => { const b = $("spectrum").getBoundingClientRect(); return (ev.clientX - b.left) * $("spectrum").width / b.width; };
  $("spectrum").addEventListener("mousedown", (ev) => { if (S.motion) S.specDrag = { a: specX(ev), b: specX(ev) }; });
  $("spectrum").addEventListener("mousemove", (ev) => { if (S.specDrag) { S.specDrag.b = specX(ev); drawSpectrum(); } });
  window.addEventListener("mouseup", (ev) => {
    const d = S.specDrag; if (!d) return;
    S.specDrag = null;
    d.b = specX(ev);
    const ny = nyquist(), clamp = (f) => Math.max(0, Math.min(ny, f));
    if (Math.abs(d.b - d.a) < 4) {
      const f = xToFreq(d.a);
      drawSpectrum();
      if (f > 0 && f <= ny) showMode(f);
    } else {
      const lo = clamp(xToFreq(Math.min(d.a, d.b))), hi = clamp(xToFreq(Math.max(d.a, d.b)));
      showDamping(lo, hi);
    }
  });
  $("opacity").addEventListener("input", () => { $("modal").style.opacity = $("opacity").value; });
  const gl = () => { $("gainlabel").textContent = "x" + $("gain").value; };
  $("gain").addEventListener("input", gl); gl();
  requestAnimationFrame(animate);
  try {
    const s = await (await api("/api/session")).json();
    if (s.live) {
      $("live").hidden = false; setupLiveExport(); connectLive();
      if (!s.live.has_spectrum) {
        for (const id of ["livespec", "spectrogram", "livepeaks", "export-live-png", "export-live-gram", "export-live-csv"]) $(id).hidden = true;
        $("gramcaption").textContent = "this pipeline has no spectrum stage: the live view shows its frames, level and stages";
      }
    }
    if (s.monitor) { $("monitor").hidden = false; pollMonitor(); }
    if (s.fps) $("fps").value = s.fps;
    if (s.video) { $("video").value = s.video; await openVideo(); }
    else if (!s.live) status("root: " + s.root + " — name a video and press Open");
  } catch (e) { showError(e.message); }
}
main();
