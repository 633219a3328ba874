// The reference reader on a library mocaplib built from sixteen sample captures
// (test/fixtures/make_fixtures.py): schema, versions, unknown keys, checksum, formula, and
// the answers to the commands of test/fixtures/queries.json, which mocaplib wrote.

import assert from "node:assert/strict";
import { readFileSync, mkdtempSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import path from "node:path";
import { test } from "node:test";
import { fileURLToPath } from "node:url";
import Ajv2020 from "ajv/dist/2020.js";
import canonicalize from "canonicalize";

import {
  LibraryReadError, SCHEMA_PATH, barycentric, blend, checkLibrary, checksumStatus,
  closestOnTriangle, contentSha256, entryAngles, entryById, numbers, ontoCone, query,
  readLibrary, series, shiftedSeries, toFrontal,
} from "../mocaplib-library.js";

const FIXTURES = path.join(path.dirname(fileURLToPath(import.meta.url)), "fixtures");
const LIBRARY = path.join(FIXTURES, "library.json");
/** mocaplib's answers to commands on LIBRARY (make_fixtures.py). */
const QUERIES = JSON.parse(readFileSync(path.join(FIXTURES, "queries.json"), "utf8"));
/** Both evaluate the same double-precision formulas; only the order of operations differs. */
const TOLERANCE = 1e-9;
const fresh = () => JSON.parse(readFileSync(LIBRARY, "utf8"));
/** The document with its checksum recomputed: a file a later mocaplib wrote. */
const resealed = (document) => ({ ...document, content_sha256: contentSha256(document) });

test("the shipped schema compiles in Ajv 2020 strict mode without a warning", () => {
  const said = [];
  const logger = { log: (m) => said.push(m), warn: (m) => said.push(m), error: (m) => said.push(m) };
  const ajv = new Ajv2020({ strict: true, allErrors: true, logger });
  ajv.compile(JSON.parse(readFileSync(SCHEMA_PATH, "utf8")));
  assert.deepEqual(said, []);
});

test("the sample library validates and its JCS checksum verifies", () => {
  const { document, checksum } = readLibrary(LIBRARY);
  assert.equal(checksum, "verified");
  assert.equal(document.format_version, 5);
  assert.equal(document.entries.length, 16);
});

test("a coefficient changed after writing is a checksum mismatch", () => {
  const document = fresh();
  document.entries[2].fourier.a[5][1] += 1e-6;
  assert.equal(checkLibrary(document).checksum, "mismatch");
});

test("version-1 and -2 checksums are Python's: reported, not judged", () => {
  const document = fresh();
  document.format_version = 2;
  assert.equal(checksumStatus(document), "python-only");
  delete document.content_sha256;
  assert.equal(checksumStatus(document), "absent");
});

test("an unknown format_version is refused", () => {
  const document = resealed({ ...fresh(), format_version: 6 });
  assert.throws(() => checkLibrary(document), /format_version 6 is not one this reader knows/);
});

test("a version-4 file without its cells' gaits or hull fails the schema", () => {
  for (const key of ["gaits", "hull"]) {
    const document = fresh();
    delete document.control_space.tetrahedra[key];
    assert.throws(() => checkLibrary(resealed(document)), /tetrahedra: must have required/);
  }
});

test("a version-3 file reads, but its tetrahedra (of all the entries) are not blended in", () => {
  const document = fresh();
  document.format_version = 3;
  const { gaits: _gaits, hull: _hull, ...tetrahedra } = document.control_space.tetrahedra;
  document.control_space.tetrahedra = tetrahedra;
  assert.equal(checkLibrary(resealed(document)).checksum, "verified");
  assert.throws(() => query(document, [1.2, 0, 0]), /format_version 3.*build it again/);
});

test("a later version's keys are ignored in open objects, refused in closed ones", () => {
  const open = [(d) => d, (d) => d.settings, (d) => d.fourier, (d) => d.entries[0],
                (d) => d.entries[0].pattern, (d) => d.entries[0].poulaine];
  for (const where of open) {
    const document = fresh();
    where(document).added_later = { any: [1, "value"] };
    assert.equal(checkLibrary(resealed(document)).checksum, "verified");
  }
  const closed = [(d) => d.skeleton, (d) => d.control_space, (d) => d.entries[0].fourier,
                  (d) => d.entries[0].root_drift, (d) => d.entries[0].poulaine.left,
                  (d) => d.entries[0].qc, (d) => d.qc_thresholds];
  for (const where of closed) {
    const document = fresh();
    where(document).added_later = 1;
    assert.throws(() => checkLibrary(resealed(document)), LibraryReadError);
  }
});

test("a broken file is refused with the schema's reason", () => {
  const document = fresh();
  document.entries[0].v = -1;
  assert.throws(() => checkLibrary(document), /\/entries\/0\/v/);
  const file = path.join(mkdtempSync(path.join(tmpdir(), "mocaplib-")), "bad.json");
  writeFileSync(file, "{not json");
  assert.throws(() => readLibrary(file), /not a JSON file/);
});

test("numbers read back unchanged through JCS (ECMAScript's number text)", () => {
  const values = numbers(fresh());
  assert.ok(values.length > 5000, `${values.length} numbers`);
  for (const value of values) assert.equal(Number(canonicalize(value)), value);
});

test("angles follow the documented formula with the ramp, periodic on [0, T)", () => {
  const { document } = readLibrary(LIBRARY);
  const entry = entryById(document, "walk_straight_normal_c1");
  const { a, b, ramp } = entry.fourier;
  const T = entry.T;
  for (const t of [0, 0.1, 0.5 * T, 0.99 * T]) {
    const q = entryAngles(entry, t);
    a.forEach((row, d) => {
      let expected = row[0] + (ramp[d] * t) / T;
      for (let k = 1; k < row.length; k++) {
        expected += row[k] * Math.cos((2 * Math.PI * k * t) / T) +
                    b[d][k] * Math.sin((2 * Math.PI * k * t) / T);
      }
      assert.ok(Math.abs(q[d] - expected) < 1e-12, `${d} at ${t}`);
    });
    const later = entryAngles(entry, t + 3 * T);
    q.forEach((value, d) => assert.ok(Math.abs(later[d] - value) < 1e-9));
  }
  // at T the next cycle starts: q(0); just before, q(0) + ramp
  const [q0, end] = [entryAngles(entry, 0), entryAngles(entry, T - 1e-12)];
  assert.deepEqual(entryAngles(entry, T), q0);
  q0.forEach((value, d) => assert.ok(Math.abs(end[d] - value - ramp[d]) < 1e-9));
});

test("a series seen from tau later is the series at t + tau (joint angles)", () => {
  const { document } = readLibrary(LIBRARY);
  const entry = entryById(document, "walk_curve_r2_left_normal_c1");
  const tau = 0.3 * entry.T;
  const shifted = shiftedSeries(entry, document.skeleton.dof_names, tau);
  const knee = document.skeleton.dof_names.indexOf("knee_flexion_l");
  for (const t of [0, 0.2, 0.7]) {
    const moved = series(shifted.a, shifted.b, entry.T, t)[knee];
    const original = series(entry.fourier.a, entry.fourier.b, entry.T, t + tau)[knee];
    assert.ok(Math.abs(moved - original) < 1e-12);
  }
});

test("a blend's weights reproduce the command's frontal speeds and blend the entries' series", () => {
  const { document } = readLibrary(LIBRARY);
  const scale = document.control_space.scale;
  const command = [1.1, 0.1, 0.05];
  const result = blend(document, command);
  assert.equal(result.inside, true);
  assert.equal(result.clamped, false);
  assert.ok(Math.abs(result.weights.reduce((s, w) => s + w, 0) - 1) < 1e-15);
  const entries = result.entries.map((id) => entryById(document, id));
  // weighed on the frontal axes: (v_f, omega, v_l), v_f = sqrt(v² − v_l²), side-steps on the cone
  const frontal = entries.map((e) => toFrontal(ontoCone([e.v, e.omega, e.v_l])));
  toFrontal(command).forEach((asked, i) => {
    const reproduced = frontal.reduce((s, f, j) => s + result.weights[j] * f[i], 0);
    assert.ok(Math.abs(reproduced - asked) < 1e-12 * scale[i] + 1e-12, `axis ${i}`);
  });
  const expectedT = entries.reduce((s, e, j) => s + result.weights[j] * e.T, 0);
  assert.ok(Math.abs(result.T - expectedT) < 1e-15);
  const a05 = entries.reduce((s, e, j) => s + result.weights[j] * e.fourier.a[0][5], 0);
  assert.ok(Math.abs(result.a[0][5] - a05) < 1e-15);
  const far = blend(document, [9, 0, 0]);
  assert.equal(far.inside, false);
  assert.ok(far.distance > 1 && far.gait === "run", JSON.stringify(far));
  assert.throws(() => blend(document, [NaN, 0, 0]), /three finite numbers/);
  assert.throws(() => query(document, [1, 0, 0], "hop"), /no hop cell/);
});

test("side-steps within 2° of ±90° go on the cone, others stay", () => {
  assert.deepEqual(ontoCone([0.4, 0.1, 0.3999]), [0.4, 0.1, 0.4]);
  assert.deepEqual(ontoCone([0.4, 0.1, -0.3999]), [0.4, 0.1, -0.4]);
  assert.deepEqual(ontoCone([0.4, 0.1, 0.39]), [0.4, 0.1, 0.39]);      // 77°: a walk
  assert.deepEqual(ontoCone([0.4, 0.1, 0.41]), [0.4, 0.1, 0.41]);      // faster sideways
  assert.deepEqual(ontoCone([0, 0.5, 0]), [0, 0.5, 0]);
});

test("the closest point of a triangle: inside its face, on an edge, at a corner", () => {
  const t = [[0, 0, 0], [1, 0, 0], [0, 1, 0]];
  assert.deepEqual(closestOnTriangle([0.2, 0.2, 3], t), { point: [0.2, 0.2, 0], d2: 9 });
  assert.deepEqual(closestOnTriangle([0.5, -1, 0], t), { point: [0.5, 0, 0], d2: 1 });
  assert.deepEqual(closestOnTriangle([-1, -1, 0], t), { point: [0, 0, 0], d2: 2 });
});

/** Weights by entry id (a tie between two tetrahedra sharing a face gives the same blend). */
function byId(entries, weights) {
  const out = new Map();
  entries.forEach((id, j) => out.set(id, (out.get(id) ?? 0) + weights[j]));
  return out;
}

test("the reader answers mocaplib's queries: cells, cone, gaps, outside, within 1e-9", () => {
  const { document } = readLibrary(LIBRARY);
  const seen = { inside: 0, clamped: 0, outside: 0, run: 0, cone: 0 };
  for (const expected of QUERIES) {
    const got = blend(document, expected.command, expected.gait_asked);
    const what = `${JSON.stringify(expected.command)} gait ${expected.gait_asked}`;
    assert.equal(got.inside, expected.inside, what);
    assert.equal(got.gait, expected.gait, what);
    assert.equal(got.clamped, expected.clamped, what);
    assert.ok(Math.abs(got.distance - expected.distance) <= TOLERANCE, what);
    got.nearest.forEach((x, i) => assert.ok(Math.abs(x - expected.nearest[i]) <= TOLERANCE, what));
    if (!expected.inside) {
      seen.outside += 1;
      continue;
    }
    seen[expected.clamped ? "clamped" : "inside"] += 1;
    seen.run += expected.gait === "run";
    seen.cone += Math.abs(ontoCone(expected.command)[2]) === expected.command[0];   // on the cone
    const [mine, theirs] = [byId(got.entries, got.weights), byId(expected.entries, expected.weights)];
    for (const id of new Set([...mine.keys(), ...theirs.keys()])) {
      assert.ok(Math.abs((mine.get(id) ?? 0) - (theirs.get(id) ?? 0)) <= TOLERANCE, `${what} ${id}`);
    }
    assert.ok(Math.abs(got.T - expected.T) <= TOLERANCE, what);
    got.drift.forEach((x, i) => assert.ok(Math.abs(x - expected.drift[i]) <= TOLERANCE, what));
  }
  // every kind of answer is compared: in each cell, on the cone, clamped in the gap, outside
  assert.ok(seen.inside > 50 && seen.clamped > 10 && seen.outside > 10, JSON.stringify(seen));
  assert.ok(seen.run > 10 && seen.cone > 15, JSON.stringify(seen));
});

test("barycentric weights of a vertex, and a library without tetrahedra", () => {
  const p = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]];
  assert.deepEqual(barycentric(p, [1, 0, 0]).map((w) => w + 0), [0, 1, 0, 0]);  // -0 is 0
  const { document } = readLibrary(LIBRARY);
  const { tetrahedra, ...flat } = document.control_space;
  assert.ok(tetrahedra.simplices.length > 0);
  assert.throws(() => blend({ ...document, control_space: flat }, [1, 0, 0]),
                /stores no tetrahedra/);
});
