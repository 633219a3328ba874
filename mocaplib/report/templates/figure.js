// The report's motion viewer: a stick figure looping an entry's cycle (or the blend of a
// control-space point picked with the mouse), posed from the Fourier series by MocapMotion
// (motion.js). Plain canvas 2-D, no libraries, works offline. Data: the JSON element with id
// "mv-data" (mocaplib/report/figureview.py).
//
// The page is a list of panels, each {draw: function (frame)} called once per animation frame
// with the current frame: {t (s), phase (0-1), q (DOF values), world (segment transforms),
// origins (segment origins, m, path frame), playing (the motion shown)}. A new view, e.g. the
// ankles' paths in the pelvis frame drawn beside the figure, is one more panel:
// window.mocapViewer.panels.push({draw: function (frame) { ... }}).
(function () {
  "use strict";
  var holder = document.getElementById("mv-data");
  var figure = document.getElementById("mv-figure");
  if (!holder || !figure || !figure.getContext || typeof MocapMotion === "undefined") { return; }
  var M = MocapMotion;
  var data = JSON.parse(holder.textContent);
  var skeleton = data.skeleton, space = data.space;
  var select = document.getElementById("mv-entry");
  var caption = document.getElementById("mv-caption");
  var pickCanvas = document.getElementById("mv-pick");
  var slider = document.getElementById("mv-vl");
  var sliderText = document.getElementById("mv-vl-value");
  var weightsText = document.getElementById("mv-weights");
  var viewer = { panels: [], playing: null, frame: null, frames: 0, pick: pick, play: playEntry };
  window.mocapViewer = viewer;

  function sideColour(name) {
    return /_l$/.test(name) ? "#1f77b4" : /_r$/.test(name) ? "#d62728" : "#333333";
  }

  function degrees(x) { return x * 180 / Math.PI; }

  function fixed(x, digits) {   // x.toFixed(digits) without "-0"
    var text = x.toFixed(digits);
    return /^-0(\.0*)?$/.test(text) ? text.slice(1) : text;
  }

  function play(motion, label) {
    var root = M.forward(skeleton, M.synthesize(motion.a, motion.b, motion.T, 0))[0];
    viewer.playing = { a: motion.a, b: motion.b, T: motion.T, drift: motion.drift,
                       locks: motion.locks, label: label, started: performance.now(),
                       height: root[11] };
  }

  function playEntry(index) {
    var e = data.entries[index];
    select.value = String(index);
    play(e, e.id + (e.mirror_of ? " (mirror image of " + e.mirror_of + ")" : ""));
  }

  function currentFrame(now) {
    var p = viewer.playing, t = (now - p.started) / 1000;
    var local = t % p.T, world;
    // the feet planted on their locks (an entry's, or those found on a blend)
    var q = M.plantedPose(skeleton, p, local);
    world = M.forward(skeleton, q);
    return { t: t, phase: local / p.T, q: q, world: world, playing: p,
             origins: world.map(function (W) { return [W[3], W[7], W[11]]; }) };
  }

  // ------------------------------------------------------------------ the figure
  var camera = { yaw: -0.9, pitch: 0.25, drag: null };
  var fctx = figure.getContext("2d");

  function project(p) {
    // look at the pelvis' height at the cycle start from yaw / pitch; z up; 1 m = 40 % of the canvas
    var x = p[0], y = p[1], z = p[2] - viewer.playing.height;
    var c = Math.cos(camera.yaw), s = Math.sin(camera.yaw), cp = Math.cos(camera.pitch), sp = Math.sin(camera.pitch);
    var u = -s * x + c * y, w = c * x + s * y;
    var v = cp * z - sp * w;
    var scale = 0.4 * Math.min(figure.width, figure.height);
    return [figure.width / 2 - scale * u, figure.height / 2 - scale * v];
  }

  function segmentLine(a, b, colour, width) {
    var p = project(a), q = project(b);
    fctx.beginPath(); fctx.strokeStyle = colour; fctx.lineWidth = width;
    fctx.moveTo(p[0], p[1]); fctx.lineTo(q[0], q[1]); fctx.stroke();
  }

  function drawFloor(frame) {
    // the world's floor grid (0.5 m) seen from the path frame, which moves with the drift
    var f = M.frame(frame.playing.drift, frame.t), c = Math.cos(f[2]), s = Math.sin(f[2]);
    function toFrame(x, y) { var dx = x - f[0], dy = y - f[1]; return [c * dx + s * dy, -s * dx + c * dy, 0]; }
    var step = 0.5, reach = 2.0;
    var x0 = Math.round(f[0] / step) * step, y0 = Math.round(f[1] / step) * step;
    for (var k = -reach; k <= reach + 1e-9; k += step) {
      segmentLine(toFrame(x0 + k, y0 - reach), toFrame(x0 + k, y0 + reach), "#e3e3e3", 1);
      segmentLine(toFrame(x0 - reach, y0 + k), toFrame(x0 + reach, y0 + k), "#e3e3e3", 1);
    }
  }

  viewer.panels.push({ draw: function (frame) {
    fctx.fillStyle = "#ffffff"; fctx.fillRect(0, 0, figure.width, figure.height);
    drawFloor(frame);
    var o = frame.origins;
    skeleton.segments.forEach(function (segment, s) {
      if (segment.parent >= 0) { segmentLine(o[segment.parent], o[s], sideColour(segment.name), 3); }
    });
    skeleton.lines.forEach(function (pair) { segmentLine(o[pair[0]], o[pair[1]], "#333333", 3); });
    Object.keys(skeleton.ends).forEach(function (key) {
      var s = Number(key), points = skeleton.ends[key].map(function (p) { return M.apply(frame.world[s], p); });
      var previous = o[s];
      points.forEach(function (p) { segmentLine(previous, p, sideColour(skeleton.segments[s].name), 3); previous = p; });
      if (points.length > 1) { segmentLine(previous, o[s], sideColour(skeleton.segments[s].name), 3); }
    });
    caption.textContent = frame.playing.label + " — phase " + frame.phase.toFixed(2) + " of " +
      frame.playing.T.toFixed(2) + " s";
  } });

  figure.addEventListener("mousedown", function (ev) { camera.drag = [ev.clientX, ev.clientY]; });
  window.addEventListener("mouseup", function () { camera.drag = null; });
  figure.addEventListener("mousemove", function (ev) {
    if (!camera.drag) { return; }
    camera.yaw += (ev.clientX - camera.drag[0]) * 0.01;
    camera.pitch = Math.max(-1.2, Math.min(1.2, camera.pitch + (ev.clientY - camera.drag[1]) * 0.01));
    camera.drag = [ev.clientX, ev.clientY];
  });

  // ------------------------------------------------------------------ the pick panel
  // omega (°/s, horizontal) against v (m/s, vertical) at the slider's v_l, as the paper's Fig. 9
  var pctx = pickCanvas ? pickCanvas.getContext("2d") : null, picked = null, box = null;
  if (space && pctx) {
    var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    space.entries.forEach(function (i) {
      data.entries[i].velocity.forEach(function (x, k) { lo[k] = Math.min(lo[k], x); hi[k] = Math.max(hi[k], x); });
    });
    var pad = [0.05 * (hi[0] - lo[0]) + 0.01, 0.05 * (hi[1] - lo[1]) + 0.01];
    box = { v: [lo[0] - pad[0], hi[0] + pad[0]], w: [lo[1] - pad[1], hi[1] + pad[1]], margin: 40 };
    slider.min = lo[2].toFixed(3); slider.max = hi[2].toFixed(3); slider.step = "0.005"; slider.value = "0";
    slider.addEventListener("input", function () {
      sliderText.textContent = fixed(Number(slider.value), 3) + " m/s";
      if (picked) { pick(picked[0], picked[1], Number(slider.value)); }
    });
    sliderText.textContent = fixed(Number(slider.value), 3) + " m/s";
    pickCanvas.addEventListener("click", function (ev) {
      var r = pickCanvas.getBoundingClientRect();
      var px = (ev.clientX - r.left) * pickCanvas.width / r.width, py = (ev.clientY - r.top) * pickCanvas.height / r.height;
      var m = box.margin, W = pickCanvas.width - 2 * m, H = pickCanvas.height - 2 * m;
      var omega = box.w[0] + (px - m) / W * (box.w[1] - box.w[0]);
      var v = box.v[0] + (pickCanvas.height - m - py) / H * (box.v[1] - box.v[0]);
      pick(v, omega, Number(slider.value));
    });
    viewer.panels.push({ draw: drawPick });
  }

  function toPick(v, omega) {
    var m = box.margin, W = pickCanvas.width - 2 * m, H = pickCanvas.height - 2 * m;
    return [m + (omega - box.w[0]) / (box.w[1] - box.w[0]) * W,
            pickCanvas.height - m - (v - box.v[0]) / (box.v[1] - box.v[0]) * H];
  }

  function drawPick() {
    pctx.fillStyle = "#ffffff"; pctx.fillRect(0, 0, pickCanvas.width, pickCanvas.height);
    var m = box.margin;
    pctx.strokeStyle = "#000000"; pctx.lineWidth = 1;
    pctx.strokeRect(m, m, pickCanvas.width - 2 * m, pickCanvas.height - 2 * m);
    pctx.fillStyle = "#000000"; pctx.font = "12px sans-serif";
    pctx.fillText("ω̂ " + fixed(degrees(box.w[0]), 0) + " … " + fixed(degrees(box.w[1]), 0) + " °/s (> 0 left)", m, pickCanvas.height - 12);
    pctx.fillText("v̂ " + fixed(box.v[0], 2) + " … " + fixed(box.v[1], 2) + " m/s", 4, 16);
    space.entries.forEach(function (i) {
      var e = data.entries[i], p = toPick(e.velocity[0], e.velocity[1]);
      pctx.beginPath(); pctx.arc(p[0], p[1], 4, 0, 2 * Math.PI);
      if (e.mirror_of) { pctx.strokeStyle = e.colour; pctx.lineWidth = 1.5; pctx.stroke(); }
      else { pctx.fillStyle = e.colour; pctx.fill(); }
    });
    if (picked) {
      var p = toPick(picked[0], picked[1]);
      pctx.strokeStyle = "#000000"; pctx.lineWidth = 2;
      pctx.beginPath(); pctx.moveTo(p[0] - 7, p[1]); pctx.lineTo(p[0] + 7, p[1]);
      pctx.moveTo(p[0], p[1] - 7); pctx.lineTo(p[0], p[1] + 7); pctx.stroke();
    }
  }

  // Blend the motion at (v, omega, v_l) (SI) in the gait cell holding it, weighed on the
  // frontal axes (side-steps on the cone, as mocaplib query); returns the weights by entry id,
  // or null when no cell holds it.
  function pick(v, omega, vl) {
    picked = [v, omega, vl];
    var found = M.weigh(space, [v, omega, vl]);
    var where = "v̂ " + fixed(v, 2) + " m/s, ω̂ " + fixed(degrees(omega), 0) + " °/s, v̂_l " + fixed(vl, 3) + " m/s";
    if (found.simplex < 0) {
      weightsText.textContent = where + ": in no gait's cell (between the walks and the runs " +
        "`mocaplib query` blends the nearest cell's nearest point; beyond them it is outside)";
      return null;
    }
    var corners = found.corners.map(function (i) { return data.entries[space.entries[i]]; });
    var blended = M.blend(corners, found.weights);
    blended.locks = M.findLocks(skeleton, blended);
    play(blended, "blend at " + where);
    var shares = {};
    corners.forEach(function (e, k) { shares[e.id] = found.weights[k]; });
    weightsText.textContent = where + ": " + space.gaits[found.simplex] + " blend of " + corners.map(function (e, k) {
      return e.id + (e.mirror_of ? " (mirror image)" : "") + " " + found.weights[k].toFixed(2);
    }).join(", ");
    return shares;
  }

  // ------------------------------------------------------------------ start
  data.entries.forEach(function (e, i) {
    var option = document.createElement("option");
    option.value = String(i);
    option.textContent = e.id + " (" + e["class"] + ")" + (e.mirror_of ? " — mirror image" : "");
    select.appendChild(option);
  });
  select.addEventListener("change", function () { playEntry(Number(select.value)); });
  playEntry(data.first);

  function step(now) {
    var frame = currentFrame(now);
    viewer.panels.forEach(function (panel) { panel.draw(frame); });
    viewer.frame = frame;
    viewer.frames += 1;
    window.requestAnimationFrame(step);
  }
  window.requestAnimationFrame(step);
})();
