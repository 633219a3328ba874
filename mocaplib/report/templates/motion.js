// Motion of library entries, in plain JavaScript (no libraries): the Fourier formula, forward
// kinematics of the skeleton as docs/library-format.md "Posing the skeleton" describes it, the
// root drift, and blending by barycentric weights in the library's own tetrahedra.
// Used by the report's figure viewer (figure.js); also loads in node (module.exports), where
// tests/test_report_motion.py compares it with mocaplib's Python.
var MocapMotion = (function () {
  "use strict";

  // q_d(t) = a[d][0] + sum_k a[d][k] cos(2 pi k t / T) + b[d][k] sin(2 pi k t / T)
  function synthesize(a, b, T, t) {
    var q = new Array(a.length);
    for (var d = 0; d < a.length; d++) {
      var value = a[d][0];
      for (var k = 1; k < a[d].length; k++) {
        var w = 2 * Math.PI * k * t / T;
        value += a[d][k] * Math.cos(w) + b[d][k] * Math.sin(w);
      }
      q[d] = value;
    }
    return q;
  }

  // 4x4 transforms as arrays of 16 numbers, row-major.
  function multiply(A, B) {
    var C = new Array(16);
    for (var i = 0; i < 4; i++) {
      for (var j = 0; j < 4; j++) {
        C[4 * i + j] = A[4 * i] * B[j] + A[4 * i + 1] * B[4 + j] + A[4 * i + 2] * B[8 + j] + A[4 * i + 3] * B[12 + j];
      }
    }
    return C;
  }

  function translation(x, y, z) { return [1, 0, 0, x, 0, 1, 0, y, 0, 0, 1, z, 0, 0, 0, 1]; }

  // Rotation by angle (rad) about a unit axis, right-hand rule (Rodrigues).
  function rotation(axis, angle) {
    var x = axis[0], y = axis[1], z = axis[2], c = Math.cos(angle), s = Math.sin(angle), v = 1 - c;
    return [c + x * x * v, x * y * v - z * s, x * z * v + y * s, 0,
            y * x * v + z * s, c + y * y * v, y * z * v - x * s, 0,
            z * x * v - y * s, z * y * v + x * s, c + z * z * v, 0,
            0, 0, 0, 1];
  }

  // Segment-to-world transforms of pose q (one value per DOF) for a skeleton
  // {segments: [{parent (index, -1 for the root), offset [x, y, z] m, dofs: [[dof index,
  // axis [x, y, z], translation (bool)], ...]}]} with parents listed before children:
  // W = W_parent . Trans(offset) . (Trans(axis q) for a translation, Rot(axis, q) else) . ...
  function forward(skeleton, q) {
    var world = [];
    skeleton.segments.forEach(function (segment) {
      var W = segment.parent < 0 ? translation(0, 0, 0) : world[segment.parent];
      W = multiply(W, translation(segment.offset[0], segment.offset[1], segment.offset[2]));
      segment.dofs.forEach(function (dof) {
        var value = q[dof[0]], axis = dof[1];
        W = multiply(W, dof[2] ? translation(axis[0] * value, axis[1] * value, axis[2] * value)
                               : rotation(axis, value));
      });
      world.push(W);
    });
    return world;
  }

  // A point p (segment frame, m) in the world: W . p.
  function apply(W, p) {
    return [W[0] * p[0] + W[1] * p[1] + W[2] * p[2] + W[3],
            W[4] * p[0] + W[5] * p[1] + W[6] * p[2] + W[7],
            W[8] * p[0] + W[9] * p[1] + W[10] * p[2] + W[11]];
  }

  // The path frame after t s of constant body velocity (u_f, u_l) m/s and turn rate omega
  // rad/s from the origin: [x, y, heading] (docs/library-format.md, root_drift).
  function frame(drift, t) {
    var phi = drift[2] * t;
    var sinc = Math.abs(phi) < 1e-8 ? 1 - phi * phi / 6 : Math.sin(phi) / phi;
    var vers = Math.abs(phi) < 1e-8 ? phi / 2 : (1 - Math.cos(phi)) / phi;
    return [t * (sinc * drift[0] - vers * drift[1]), t * (vers * drift[0] + sinc * drift[1]), phi];
  }

  // A command [v, omega, v_l] with a pure side-step put on the cone |v_l| = v, as
  // mocaplib.library.cells.onto_cone: v_l = ±v when v > 0 and cos(2°) v <= |v_l| <= v (1 + 1e-9).
  function ontoCone(command) {
    var v = command[0], lateral = Math.abs(command[2]);
    var side = v > 0 && lateral >= Math.cos(2 * (Math.PI / 180)) * v && lateral <= v * (1 + 1e-9);
    return side ? [v, command[1], Math.sign(command[2]) * v] : command.slice();
  }

  // The tetrahedron of space.simplices (rows of 4 point indices) holding the normalised point
  // x, and its barycentric weights, as mocaplib.controlspace.locate finds them: among the
  // tetrahedra whose smallest weight is >= -tol, the one with the largest smallest weight.
  // Returns {simplex: index or -1 (outside), weights: [4 numbers] or null}.
  function locate(space, x, tol) {
    tol = tol === undefined ? 1e-9 : tol;
    var best = -1, bestWorst = -Infinity, bestWeights = null;
    space.simplices.forEach(function (simplex, s) {
      var p = simplex.map(function (i) { return space.points[i]; });
      var o = p[3], a = sub(p[0], o), b = sub(p[1], o), c = sub(p[2], o);
      var rows = [cross(b, c), cross(c, a), cross(a, b)], det = dot(a, rows[0]);
      var r = sub(x, o);
      var w = rows.map(function (row) { return dot(row, r) / det; });
      w.push(1 - w[0] - w[1] - w[2]);
      var worst = Math.min.apply(null, w);
      if (worst > bestWorst) { best = s; bestWorst = worst; bestWeights = w; }
    });
    return bestWorst >= -tol ? { simplex: best, weights: bestWeights } : { simplex: -1, weights: null };
  }

  // Where the viewer blends a command [v, omega, v_l] (SI), as `mocaplib query` weighs a
  // command inside a gait cell: located (on the cone, / scale) in space.simplices; then
  // weighed on the frontal axes [sqrt(v² − v_l²), omega, v_l] / scale in that gait's frontal
  // tetrahedra (space.frontal), or at the nearest point of their boundary when outside them
  // (mocaplib.library.cells.weigh_on_frontal_axes). Returns {simplex: index into
  // space.simplices (its gait) or -1 (in no cell), corners: 4 point indices, weights: 4}.
  function weigh(space, command) {
    var coned = ontoCone(command);
    var x = coned.map(function (p, k) { return p / space.scale[k]; });
    var found = locate(space, x);
    if (found.simplex < 0) { return { simplex: -1, corners: null, weights: null }; }
    var gait = space.gaits[found.simplex];
    var frontal = { points: space.frontal.points, simplices: space.frontal.simplices.filter(
      function (s, k) { return space.frontal.gaits[k] === gait; }) };
    var f = [Math.sqrt(Math.max(coned[0] * coned[0] - coned[2] * coned[2], 0)), coned[1], coned[2]]
      .map(function (p, k) { return p / space.scale[k]; });
    var weighed = frontal.simplices.length ? locate(frontal, f) : { simplex: -1 };
    if (frontal.simplices.length && weighed.simplex < 0) {
      weighed = locate(frontal, nearestOnBoundary(frontal, f), 1e-7);
    }
    return weighed.simplex < 0
      ? { simplex: found.simplex, corners: space.simplices[found.simplex], weights: found.weights }
      : { simplex: found.simplex, corners: frontal.simplices[weighed.simplex], weights: weighed.weights };
  }

  // The nearest point to x of the triangles that only one of the tetrahedra
  // tetra.simplices has (their boundary), tetra.points their vertices.
  function nearestOnBoundary(tetra, x) {
    var count = {};
    tetra.simplices.forEach(function (s) {
      [0, 1, 2, 3].forEach(function (drop) {
        var key = s.filter(function (_, k) { return k !== drop; })
          .sort(function (i, j) { return i - j; }).join(",");
        count[key] = (count[key] || 0) + 1;
      });
    });
    var best = null, bestD2 = Infinity;
    Object.keys(count).sort(byVertices).forEach(function (key) {
      if (count[key] !== 1) { return; }
      var c = closestOnTriangle(x, key.split(",").map(function (i) { return tetra.points[+i]; }));
      if (c.d2 < bestD2) { best = c.point; bestD2 = c.d2; }
    });
    return best;
  }

  function byVertices(f, g) {
    var a = f.split(",").map(Number), b = g.split(",").map(Number);
    return a[0] - b[0] || a[1] - b[1] || a[2] - b[2];
  }

  // The closest point of triangle [A, B, C] to p and its squared distance: the projection
  // onto its plane when inside it, else the closest point of its edges.
  function closestOnTriangle(p, t) {
    var A = t[0], B = t[1], C = t[2], n = cross(sub(B, A), sub(C, A));
    var proj = sub(p, scaled(dot(sub(p, A), n) / dot(n, n), n));
    var edges = [[A, B], [B, C], [C, A]];
    if (edges.every(function (e) { return dot(cross(sub(e[1], e[0]), sub(proj, e[0])), n) >= 0; })) {
      return { point: proj, d2: dot(sub(p, proj), sub(p, proj)) };
    }
    var best = { point: null, d2: Infinity };
    edges.forEach(function (e) {
      var d = sub(e[1], e[0]);
      var s = Math.min(Math.max(dot(sub(p, e[0]), d) / dot(d, d), 0), 1);
      var c = sub(e[0], scaled(-s, d)), d2 = dot(sub(p, c), sub(p, c));
      if (d2 < best.d2) { best = { point: c, d2: d2 }; }
    });
    return best;
  }

  function scaled(s, u) { return [s * u[0], s * u[1], s * u[2]]; }
  function sub(u, v) { return [u[0] - v[0], u[1] - v[1], u[2] - v[2]]; }
  function add(u, v) { return [u[0] + v[0], u[1] + v[1], u[2] + v[2]]; }
  function dot(u, v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; }
  function cross(u, v) { return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]; }

  // Weighted sum of entries' coefficients (shorter rows padded with zeros), periods and
  // drifts: equations (4)-(6) of Truong et al. 2010, as mocaplib.controlspace blends.
  function blend(entries, weights) {
    var D = entries[0].a.length, N = 0;
    entries.forEach(function (e) { e.a.forEach(function (row) { N = Math.max(N, row.length); }); });
    var out = { a: [], b: [], T: 0, drift: [0, 0, 0] };
    for (var d = 0; d < D; d++) { out.a.push(new Array(N).fill(0)); out.b.push(new Array(N).fill(0)); }
    entries.forEach(function (e, i) {
      var w = weights[i];
      for (var d = 0; d < D; d++) {
        for (var k = 0; k < e.a[d].length; k++) { out.a[d][k] += w * e.a[d][k]; out.b[d][k] += w * e.b[d][k]; }
      }
      out.T += w * e.T;
      for (var j = 0; j < 3; j++) { out.drift[j] += w * e.drift[j]; }
    });
    return out;
  }


  // ---------------------------------------------------------------- planted feet
  // An entry's series rounds its stances off (mocaplib.library.planting.PlantedSeries); each
  // frame is posed from the series and then, as mocaplib.library.planting plants a motion,
  // each leg moved so that its foot meets its lock: from entry.locks, rows [foot (0 left, 1
  // right), t0, t1 (s from the cycle's start), heel x, y (m), heading (rad)] in the path frame
  // at t = 0, the foot locked between t0 and t1, its heel (or, when its toes point down, its
  // toe, a sole's length ahead) on the floor there with the foot's pitch of the series (or,
  // where the leg cannot reach that, the pitch nearest it that it reaches); within
  // skeleton.fade_s of a lock the leg takes the lock's correction at its end, weighted by a
  // smoothstep, and its foot stays above the floor by skeleton.approach_speed times the time
  // to the lock (times the share of skeleton.fade_s still ahead); a foot below the floor (or
  // that height) is raised onto it.
  var REACH_STEPS = 8, REACH_TOLERANCE = 1e-7, REACH_DAMPING = 1e-8, DIFFERENCE = 1e-6;

  // The ankle, heel and toe (m) of foot {segment, dofs, knee} in pose q: 9 numbers.
  function footPoints(skeleton, q, foot) {
    var W = forward(skeleton, q)[foot.segment], sole = skeleton.ends[foot.segment];
    var heel = apply(W, sole[0]), toe = apply(W, sole[1]);
    return [W[3], W[7], W[11], heel[0], heel[1], heel[2], toe[0], toe[1], toe[2]];
  }

  // x of A x = b (n x n, Gaussian elimination with partial pivoting).
  function solveLinear(A, b) {
    var n = b.length, M = A.map(function (row, i) { return row.concat([b[i]]); });
    for (var c = 0; c < n; c++) {
      var p = c;
      for (var r = c + 1; r < n; r++) { if (Math.abs(M[r][c]) > Math.abs(M[p][c])) { p = r; } }
      var swap = M[c]; M[c] = M[p]; M[p] = swap;
      for (var r2 = c + 1; r2 < n; r2++) {
        var f = M[r2][c] / M[c][c];
        for (var k = c; k <= n; k++) { M[r2][k] -= f * M[c][k]; }
      }
    }
    var x = new Array(n);
    for (var i = n - 1; i >= 0; i--) {
      var s = M[i][n];
      for (var j = i + 1; j < n; j++) { s -= M[i][j] * x[j]; }
      x[i] = s / M[i][i];
    }
    return x;
  }

  // Pose q with its leg's DOFs (foot.dofs) moved so that the foot's ankle, heel and toe reach
  // targets (9 numbers, m): damped Gauss-Newton steps on a forward-difference Jacobian from
  // the knee bent skeleton.knee_start at least (at a straight knee the Jacobian cannot tell
  // bending from straightening), the knee kept at 0 or more, until no DOF moves by
  // REACH_TOLERANCE rad.
  function reach(skeleton, q, foot, targets) {
    q = q.slice();
    q[foot.knee] = Math.max(q[foot.knee], skeleton.knee_start);
    for (var step = 0; step < REACH_STEPS; step++) {
      var p = footPoints(skeleton, q, foot);
      var columns = foot.dofs.map(function (d) {
        var moved = q.slice();
        moved[d] += DIFFERENCE;
        return footPoints(skeleton, moved, foot).map(function (x, i) { return (x - p[i]) / DIFFERENCE; });
      });
      var gap = targets.map(function (x, i) { return x - p[i]; });
      var normal = columns.map(function (u, i) {
        return columns.map(function (v, j) { return dot9(u, v) + (i === j ? REACH_DAMPING : 0); });
      });
      var change = solveLinear(normal, columns.map(function (u) { return dot9(u, gap); }));
      var largest = 0;
      foot.dofs.forEach(function (d, k) {
        var before = q[d];
        q[d] = d === foot.knee ? Math.max(q[d] + change[k], 0) : q[d] + change[k];
        largest = Math.max(largest, Math.abs(q[d] - before));
      });
      if (largest < REACH_TOLERANCE) { break; }
    }
    return q;
  }

  function dot9(u, v) { var s = 0; for (var i = 0; i < 9; i++) { s += u[i] * v[i]; } return s; }

  // Where the ankle, heel and toe of a foot locked by `lock` go at time t (s) of a motion
  // moving along drift, the foot pitched `pitch` (rad): 9 numbers in the path frame at t.
  function lockedFoot(skeleton, foot, lock, drift, t, pitch) {
    var f = frame(drift, t), c = Math.cos(f[2]), s = Math.sin(f[2]);
    var dx = lock[3] - f[0], dy = lock[4] - f[1], psi = lock[5] - f[2];
    var sole = skeleton.ends[foot.segment], length = sole[1][0] - sole[0][0];
    var heel = [c * dx + s * dy, -s * dx + c * dy, 0];
    var toe = [heel[0] + length * Math.cos(psi), heel[1] + length * Math.sin(psi), 0];
    var x = [Math.cos(pitch) * Math.cos(psi), Math.cos(pitch) * Math.sin(psi), Math.sin(pitch)];
    var y = [-Math.sin(psi), Math.cos(psi), 0], z = cross(x, y);
    var placed = [[0, 0, 0], sole[0], sole[1]].map(function (p) {
      return [0, 1, 2].map(function (i) { return x[i] * p[0] + y[i] * p[1] + z[i] * p[2]; });
    });
    var pivot = pitch >= 0 ? sub(heel, placed[1]) : sub(toe, placed[2]);
    return [].concat.apply([], placed.map(function (p) { return add(p, pivot); }));
  }

  // The pitch (rad, toes up > 0) of foot's segment in pose q.
  function footPitch(skeleton, q, foot) {
    var W = forward(skeleton, q)[foot.segment];
    return Math.atan2(W[8], Math.hypot(W[0], W[4]));
  }

  // The pitch (rad) of a foot locked by `lock` at time t, from its pitch in pose q: kept
  // where the leg reaches the ankle with its knee bent skeleton.stance_knee at least, else the
  // pitch nearest it, rolling on the heel (>= 0) or the toe (< 0), that puts the ankle at that
  // reach from the hip (as the planting's stance pitch does).
  function reachablePitch(skeleton, q, foot, lock, drift, t) {
    var pitch = footPitch(skeleton, q, foot), bent = q.slice();
    bent[foot.knee] = skeleton.stance_knee;
    var B = forward(skeleton, bent), thigh = B[foot.hip], sole = B[foot.segment];
    var hip = [thigh[3], thigh[7], thigh[11]], straight = sub([sole[3], sole[7], sole[11]], hip);
    var reach2 = dot(straight, straight);
    var at = lockedFoot(skeleton, foot, lock, drift, t, pitch), ankle = sub(at.slice(0, 3), hip);
    if (dot(ankle, ankle) <= reach2) { return pitch; }
    var ends = skeleton.ends[foot.segment], heading = lock[5] - frame(drift, t)[2];
    var along = [Math.cos(heading), Math.sin(heading), 0];
    var level = lockedFoot(skeleton, foot, lock, drift, t, 0);
    var best = pitch, miss = Infinity;
    [[1, level.slice(3, 6), ends[0]], [-1, level.slice(6, 9), ends[1]]].forEach(function (pivot) {
      var sign = pivot[0], d = sub(pivot[1], hip), point = pivot[2];
      var rest = Math.atan2(-point[2], -point[0]), arm = Math.hypot(point[0], point[2]);
      var df = dot(d, along), span = Math.max(2 * arm * Math.hypot(df, d[2]), 1e-12);
      var cosine = Math.min(1, Math.max(-1, (reach2 - dot(d, d) - arm * arm) / span));
      [Math.acos(cosine), -Math.acos(cosine)].forEach(function (root) {
        var theta = Math.atan2(d[2], df) + root - rest;
        theta = Math.atan2(Math.sin(theta), Math.cos(theta));
        theta = sign * Math.max(sign * theta, 0);
        if (Math.abs(theta - pitch) < miss) { best = theta; miss = Math.abs(theta - pitch); }
      });
    });
    return best;
  }

  // Pose q (the series at time t within the cycle) moved so that the foot of `side` meets
  // lock at time t.
  function locked(skeleton, q, side, lock, drift, t) {
    var foot = skeleton.feet[side];
    return reach(skeleton, q, foot, lockedFoot(skeleton, foot, lock, drift, t,
                                               reachablePitch(skeleton, q, foot, lock, drift, t)));
  }

  // How far (rad) the leg DOFs of the foot of `side` move, in pose q of entry at time t, to
  // meet lock at t.
  function correction(skeleton, entry, side, lock, t, q) {
    var moved = locked(skeleton, q, side, lock, entry.drift, t);
    return skeleton.feet[side].dofs.map(function (d) { return moved[d] - q[d]; });
  }

  // The correction at a lock's end (time edge, s), computed once for each lock and end (a
  // page's lock belongs to one entry on one skeleton).
  var edgeCorrections = new WeakMap();
  function edgeCorrection(skeleton, entry, side, lock, edge) {
    var ends = edgeCorrections.get(lock) || {};
    if (!(edge in ends)) {
      ends[edge] = correction(skeleton, entry, side, lock, edge,
                              synthesize(entry.a, entry.b, entry.T, edge));
      edgeCorrections.set(lock, ends);
    }
    return ends[edge];
  }

  // The pose of an entry {a, b, T, drift, locks} at time t (s) of its cycle (path frame),
  // its feet planted (above).
  function plantedPose(skeleton, entry, t) {
    var q = synthesize(entry.a, entry.b, entry.T, t), out = q.slice();
    var fade = skeleton.fade_s, clearance = [0, 0];
    skeleton.feet.forEach(function (foot, side) {
      var near = null, weight = 0, edge = 0;
      (entry.locks || []).forEach(function (lock) {
        if (lock[0] !== side) { return; }
        if (t >= lock[1] && t <= lock[2]) { near = lock; weight = 1; edge = t; return; }
        var d = t < lock[1] ? lock[1] - t : t - lock[2];
        var w = d < fade ? 1 - d / fade : 0;
        w = w * w * (3 - 2 * w);
        if (w > weight) {
          near = lock; weight = w; edge = t < lock[1] ? lock[1] : lock[2];
          clearance[side] = skeleton.approach_speed * d * (1 - d / fade);
        }
      });
      if (!near) { return; }
      var change = edge === t ? correction(skeleton, entry, side, near, t, q)
                              : edgeCorrection(skeleton, entry, side, near, edge);
      foot.dofs.forEach(function (d, k) { out[d] += weight * change[k]; });
    });
    skeleton.feet.forEach(function (foot, side) {
      var p = footPoints(skeleton, out, foot), short = clearance[side] - Math.min(p[5], p[8]);
      if (short > 0) {
        out = reach(skeleton, out, foot, p.map(function (x, i) { return i % 3 === 2 ? x + short : x; }));
      }
    });
    return out;
  }

  // ---------------------------------------------------------------- locks of a blend
  // The locks (as entry.locks) of a motion {a, b, T, drift} that has none, a blend of
  // entries: its stances found as mocaplib.library.planting.stance_frames finds them
  // (skeleton.stance holds its constants), on the heel and toe sampled at skeleton.stance.rate
  // Hz or a little more (a whole number of samples a cycle) over three cycles, one before and
  // one after, so that a stance across the cycle's ends is seen whole; each stance within
  // skeleton.fade_s of the cycle locked where its foot lies flattest (the higher of heel and
  // toe lowest), with its heel's place and its foot's heading there.
  function findLocks(skeleton, motion) {
    var rule = skeleton.stance, count = Math.ceil(motion.T * rule.rate), rate = count / motion.T;
    var cycle = [];                       // per sample of one cycle, per foot: heel, toe, heading
    for (var k = 0; k < count; k++) {
      var W = forward(skeleton, synthesize(motion.a, motion.b, motion.T, k / rate));
      cycle.push(skeleton.feet.map(function (foot) {
        var F = W[foot.segment], sole = skeleton.ends[foot.segment];
        return [apply(F, sole[0]), apply(F, sole[1]), Math.atan2(F[4], F[0])];
      }));
    }
    var soles = [];                       // (3 count) x 2 feet x [heel, toe, heading], world
    for (var i = 0; i < 3 * count; i++) {
      var f = frame(motion.drift, (i - count) / rate), c = Math.cos(f[2]), s = Math.sin(f[2]);
      soles.push(cycle[i % count].map(function (foot) {
        return [0, 1].map(function (p) {
          var x = foot[p];
          return [f[0] + c * x[0] - s * x[1], f[1] + s * x[0] + c * x[1], x[2]];
        }).concat([foot[2] + f[2]]);
      }));
    }
    var locks = [];
    [0, 1].forEach(function (side) {
      stanceRuns(soles.map(function (feet) { return feet[side]; }), rate, rule)
        .forEach(function (run) {
          var t0 = (run[0] - count) / rate, t1 = (run[1] - 1 - count) / rate;
          if (t1 < -skeleton.fade_s || t0 > motion.T + skeleton.fade_s) { return; }
          var flat = run[0];
          for (var j = run[0]; j < run[1]; j++) {
            if (higher(soles[j][side]) < higher(soles[flat][side])) { flat = j; }
          }
          var foot = soles[flat][side];
          locks.push([side, t0, t1, foot[0][0], foot[0][1], foot[2]]);
        });
    });
    return locks;
  }

  function higher(foot) { return Math.max(foot[0][2], foot[1][2]); }

  // The stance runs [start, stop) of one foot's samples [heel, toe, ...] (m) at rate Hz, by
  // the rule of mocaplib.library.planting._stance: contact where the slower sole point moves
  // at most contact_speed and the lower lies within contact_rise of the foot's standing level
  // (the median height of its lower point where it is still), gaps of stance_gap_s bridged;
  // contact runs joined where the foot stays slow and within roll_rise of the level between
  // them and one sole point stays within roll_shift; runs of min_stance_s at least.
  function stanceRuns(samples, rate, rule) {
    var n = samples.length, low = [], speed = [];
    samples.forEach(function (foot, i) {
      low.push(Math.min(foot[0][2], foot[1][2]));
      var a = samples[Math.max(i - 1, 0)], b = samples[Math.min(i + 1, n - 1)];
      var span = (Math.min(i + 1, n - 1) - Math.max(i - 1, 0)) / rate;
      speed.push(Math.min.apply(null, [0, 1].map(function (p) {
        return Math.hypot(b[p][0] - a[p][0], b[p][1] - a[p][1]) / span;
      })));
    });
    var still = low.filter(function (_, i) { return speed[i] < rule.still_speed; });
    if (!still.length) { return []; }
    var level = median(still);
    if (level > rule.max_level) { return []; }
    var slow = speed.map(function (v) { return v <= rule.contact_speed; });
    var contact = slow.map(function (v, i) { return v && low[i] <= level + rule.contact_rise; });
    var near = slow.map(function (v, i) { return v && low[i] <= level + rule.roll_rise; });
    var bridge = Math.max(1, Math.round(rule.stance_gap_s * rate));
    var shortest = Math.max(1, Math.round(rule.min_stance_s * rate));
    [contact, near].forEach(function (mask) {
      runsOf(mask.map(function (v) { return !v; })).forEach(function (gap) {
        if (gap[0] > 0 && gap[1] < n && gap[1] - gap[0] <= bridge) {
          for (var i = gap[0]; i < gap[1]; i++) { mask[i] = true; }
        }
      });
    });
    var out = [];
    runsOf(near).forEach(function (span) {
      var joined = [];
      runsOf(contact.slice(span[0], span[1])).forEach(function (run) {
        var a = span[0] + run[0], b = span[0] + run[1], last = joined[joined.length - 1];
        if (last && stays(samples[last[1] - 1], samples[a], rule.roll_shift)) {
          last[1] = b;
        } else {
          joined.push([a, b]);
        }
      });
      joined.forEach(function (run) { if (run[1] - run[0] >= shortest) { out.push(run); } });
    });
    return out;
  }

  // The [start, stop) ranges where mask is true.
  function runsOf(mask) {
    var out = [];
    mask.forEach(function (v, i) {
      if (!v) { return; }
      if (i > 0 && mask[i - 1]) { out[out.length - 1][1] = i + 1; } else { out.push([i, i + 1]); }
    });
    return out;
  }

  // Whether heel or toe lies within shift (m) of its place, horizontally, from sample a to b.
  function stays(a, b, shift) {
    return Math.min(Math.hypot(b[0][0] - a[0][0], b[0][1] - a[0][1]),
                    Math.hypot(b[1][0] - a[1][0], b[1][1] - a[1][1])) <= shift;
  }

  function median(values) {
    var v = values.slice().sort(function (x, y) { return x - y; }), m = v.length >> 1;
    return v.length % 2 ? v[m] : (v[m - 1] + v[m]) / 2;
  }

  return { synthesize: synthesize, forward: forward, apply: apply, frame: frame,
           ontoCone: ontoCone, locate: locate, weigh: weigh, blend: blend,
           plantedPose: plantedPose, findLocks: findLocks };
})();
if (typeof module !== "undefined") { module.exports = MocapMotion; }
