// Interactive 3-D view of the control space: plain canvas, no libraries, works offline.
// Data: the JSON element with id "cs-data". Drag to rotate, wheel to zoom, hover for the entry.
(function () {
  "use strict";
  var holder = document.getElementById("cs-data");
  var canvas = document.getElementById("cs-viewer");
  if (!holder || !canvas || !canvas.getContext) { return; }
  var data = JSON.parse(holder.textContent);
  var tip = document.getElementById("cs-tip");
  var ctx = canvas.getContext("2d");
  var pts = data.points, env = data.envelope.points;
  var all = pts.concat(env);
  var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  all.forEach(function (p) { for (var k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); } });
  var mid = [0, 1, 2].map(function (k) { return (lo[k] + hi[k]) / 2; });
  var span = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) || 1;
  // Start as the static picture: v̂ to the right, ω̂ into the page, v̂_l up, from a little above.
  var yaw = -0.35, pitch = 0.4, zoom = 1.0, drag = null, projected = [];

  function project(p) {
    // Data axes (x, y, z) drawn with z up; rotate about z (yaw) then tilt (pitch).
    var x = p[0] - mid[0], y = p[1] - mid[1], z = p[2] - mid[2];
    var cx = Math.cos(yaw), sx = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
    var u = cx * x - sx * y, w = sx * x + cx * y;
    var v = cp * z - sp * w, depth = sp * z + cp * w;
    var s = zoom * 0.6 * Math.min(canvas.width, canvas.height) / span;
    return [canvas.width / 2 + s * u, canvas.height / 2 - s * v, depth];
  }

  function line(a, b, colour, width, dash) {
    ctx.beginPath(); ctx.setLineDash(dash || []); ctx.strokeStyle = colour; ctx.lineWidth = width;
    ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke(); ctx.setLineDash([]);
  }

  function draw() {
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    ctx.fillStyle = "#ffffff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    var origin = [lo[0], lo[1], lo[2]];
    for (var k = 0; k < 3; k++) {
      var end = origin.slice(); end[k] = hi[k];
      var a = project(origin), b = project(end);
      line(a, b, "#000000", 1.5);
      ctx.fillStyle = "#000000"; ctx.font = "12px sans-serif";
      var tw = ctx.measureText(data.axes[k]).width;  // keep the label inside the canvas
      ctx.fillText(data.axes[k], Math.max(4, Math.min(b[0] + 4, canvas.width - tw - 4)),
                   Math.max(14, Math.min(b[1] - 4, canvas.height - 4)));
    }
    data.envelope.edges.forEach(function (e) { line(project(env[e[0]]), project(env[e[1]]), "rgba(214,39,40,0.45)", 1, [4, 3]); });
    projected = pts.map(function (p, i) { var q = project(p); q.push(i); return q; });  // [x, y, depth, i]
    data.edges.forEach(function (e) { line(projected[e[0]], projected[e[1]], "rgba(110,110,110,0.55)", 1); });
    projected.slice().sort(function (a, b) { return a[2] - b[2]; }).forEach(function (q) {
      ctx.beginPath(); ctx.arc(q[0], q[1], 6, 0, 2 * Math.PI);
      ctx.fillStyle = data.colours[data.classes[q[3]]] || "#808080"; ctx.fill();
      ctx.lineWidth = 1; ctx.strokeStyle = "#000000"; ctx.stroke();
    });
    canvas.setAttribute("data-drawn", String(projected.length));
  }

  canvas.addEventListener("mousedown", function (ev) { drag = [ev.clientX, ev.clientY]; });
  window.addEventListener("mouseup", function () { drag = null; });
  canvas.addEventListener("mousemove", function (ev) {
    var r = canvas.getBoundingClientRect();
    var mx = (ev.clientX - r.left) * canvas.width / r.width, my = (ev.clientY - r.top) * canvas.height / r.height;
    if (drag) {
      yaw += (ev.clientX - drag[0]) * 0.01;
      pitch = Math.max(-1.5, Math.min(1.5, pitch + (ev.clientY - drag[1]) * 0.01));
      drag = [ev.clientX, ev.clientY]; draw(); return;
    }
    var best = null;
    projected.forEach(function (q) { var d = Math.hypot(q[0] - mx, q[1] - my); if (d < 9 && (!best || d < best.dist)) { best = { dist: d, i: q[3] }; } });
    if (tip) { tip.textContent = best ? data.ids[best.i] + " (" + data.classes[best.i] + "): " + data.velocities[best.i] : "\u00a0"; }
  });
  canvas.addEventListener("wheel", function (ev) {
    ev.preventDefault(); zoom = Math.max(0.3, Math.min(5, zoom * (ev.deltaY < 0 ? 1.1 : 0.9))); draw();
  }, { passive: false });
  draw();
})();
