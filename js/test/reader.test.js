// The reference reader on a library mocaplib built from seven sample captures
// (test/fixtures/make_fixtures.py): schema, versions, unknown keys, checksum, formula, blend.

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
  contentSha256, entryAngles, entryById, numbers, readLibrary, series, shiftedSeries,
} from "../mocaplib-library.js";

const FIXTURES = path.join(path.dirname(fileURLToPath(import.meta.url)), "fixtures");
const LIBRARY = path.join(FIXTURES, "library.json");
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
  assert.equal(document.format_version, 3);
  assert.equal(document.entries.length, 7);
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
  const document = resealed({ ...fresh(), format_version: 4 });
  assert.throws(() => checkLibrary(document), /format_version 4 is not one this reader knows/);
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

test("a blend's weights reproduce the command and blend the entries' series", () => {
  const { document } = readLibrary(LIBRARY);
  const scale = document.control_space.scale;
  const command = [1.1, 0.1, 0.05];
  const result = blend(document, command);
  assert.equal(result.inside, true);
  assert.ok(Math.abs(result.weights.reduce((s, w) => s + w, 0) - 1) < 1e-15);
  const entries = result.entries.map((id) => entryById(document, id));
  ["v", "omega", "v_l"].forEach((key, i) => {
    const reproduced = entries.reduce((s, e, j) => s + result.weights[j] * e[key], 0);
    assert.ok(Math.abs(reproduced - command[i]) < 1e-12 * scale[i] + 1e-12, key);
  });
  const expectedT = entries.reduce((s, e, j) => s + result.weights[j] * e.T, 0);
  assert.ok(Math.abs(result.T - expectedT) < 1e-15);
  const a05 = entries.reduce((s, e, j) => s + result.weights[j] * e.fourier.a[0][5], 0);
  assert.ok(Math.abs(result.a[0][5] - a05) < 1e-15);
  assert.deepEqual(blend(document, [9, 0, 0]), { inside: false });
  assert.throws(() => blend(document, [NaN, 0, 0]), /three finite numbers/);
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
