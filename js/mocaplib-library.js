// Reference reader of mocaplib motion library files: docs/library-format.md as code.
//
// readLibrary(path)            parse, refuse an unknown format_version, validate against the
//                              shipped JSON Schema (Ajv, draft 2020-12, strict), verify the
//                              content checksum (RFC 8785 / JCS + SHA-256)
// entryAngles(entry, t)        an entry's coordinates at t seconds (the documented formula,
//                              ramp included; periodic on [0, T))
// query(library, command, gait) where a velocity command (v m/s, omega rad/s, v_l m/s) is
//                              blended, as `mocaplib query` answers it: the gait cell, its
//                              four entries and weights, clamped between the cells, or
//                              outside, in the cells the file stores (control_space.tetrahedra)
// blend(library, command, gait) that answer with the blended series, period and drift
//
// Run as a script: node mocaplib-library.js LIBRARY.json [--phases N] [--gait GAIT]
//   [--query V OMEGA VL]...   prints a JSON report (used by the Python tests).
//
// Python's validation (mocaplib validate) checks more than the schema (coefficient shapes,
// periods, sorted ids, the control space's geometry); this reader checks what a file needs
// to be read: the schema, the version and the checksum.

import { createHash } from "node:crypto";
import { readFileSync } from "node:fs";
import { fileURLToPath } from "node:url";
import path from "node:path";
import Ajv2020 from "ajv/dist/2020.js";
import canonicalize from "canonicalize";

const HERE = path.dirname(fileURLToPath(import.meta.url));
/** The JSON Schema mocaplib ships (mocaplib/schema/library.schema.json). */
export const SCHEMA_PATH = path.join(HERE, "..", "mocaplib", "schema", "library.schema.json");
export const FORMAT = "mocaplib-library";
/** The versions this reader knows (docs/library-format.md, Versions). */
export const KNOWN_VERSIONS = [1, 2, 3, 4, 5];
/** The first version whose stored tetrahedra are the gait cells (with gaits and hull). */
export const GAIT_CELLS_VERSION = 4;
/** The first version that stores each cell's frontal tetrahedra, where weights are computed. */
export const FRONTAL_WEIGHTS_VERSION = 5;
/** Versions whose checksum is Python-printed JSON, which only Python reproduces. */
export const PYTHON_CHECKSUM_VERSIONS = [1, 2];
/** Root channels (pelvis_tx, pelvis_ty, pelvis_rotation) by name, for re-anchoring. */
const ROOT_NAMES = ["pelvis_tx", "pelvis_ty", "pelvis_rotation"];
/** Largest angle (rad) from ±90° of a pure side-step: its point is put on the cone. */
export const SIDEWAYS_TOLERANCE = 2 * (Math.PI / 180);
/** A command within this normalised distance of a cell (or of the hull) is inside it. */
export const HULL_TOLERANCE = 1e-6;
/** Barycentric tolerance of locating a command in the tetrahedra. */
export const WEIGHT_TOLERANCE = 1e-9;
/** Barycentric tolerance of locating a command's nearest point on a cell in its tetrahedra. */
const BOUNDARY_WEIGHT_TOLERANCE = 1e-7;

export class LibraryReadError extends Error {}

let compiledSchema = null;

/** The Ajv validator of the shipped schema (compiled once; strict mode, all errors). */
export function schemaValidator(schemaPath = SCHEMA_PATH) {
  if (compiledSchema === null || schemaPath !== SCHEMA_PATH) {
    const ajv = new Ajv2020({ strict: true, allErrors: true });
    const validate = ajv.compile(JSON.parse(readFileSync(schemaPath, "utf8")));
    if (schemaPath !== SCHEMA_PATH) return validate;
    compiledSchema = validate;
  }
  return compiledSchema;
}

/** The schema's problems of a parsed document: ["/entries/0/T: must be number", ...]. */
export function schemaProblems(document) {
  const validate = schemaValidator();
  if (validate(document)) return [];
  return validate.errors.map((e) => `${e.instancePath || "(document)"}: ${e.message}`);
}

/** SHA-256 (hex) of the RFC 8785 form of the document without content_sha256. */
export function contentSha256(document) {
  const { content_sha256: _stored, ...content } = document;
  return createHash("sha256").update(canonicalize(content), "utf8").digest("hex");
}

/**
 * "verified", "mismatch", "absent" (no checksum) or "python-only" (a version-1 or -2 file:
 * its checksum is Python-printed JSON, which this reader does not reproduce).
 */
export function checksumStatus(document) {
  if (document.content_sha256 === undefined) return "absent";
  if (PYTHON_CHECKSUM_VERSIONS.includes(document.format_version)) return "python-only";
  return contentSha256(document) === document.content_sha256 ? "verified" : "mismatch";
}

/**
 * Read a library file: {document, checksum}. Throws LibraryReadError for a file that is not
 * a library, of an unknown version, or failing the schema. A checksum mismatch is reported,
 * not thrown (the values are readable, just not the ones mocaplib wrote).
 */
export function readLibrary(file) {
  let document;
  try {
    document = JSON.parse(readFileSync(file, "utf8"));
  } catch (error) {
    throw new LibraryReadError(`${file}: not a JSON file: ${error.message}`);
  }
  return checkLibrary(document, file);
}

/** The checks of readLibrary on a parsed document. */
export function checkLibrary(document, file = "(document)") {
  if (document === null || typeof document !== "object" || document.format !== FORMAT) {
    throw new LibraryReadError(`${file}: not a mocaplib library (format is not "${FORMAT}")`);
  }
  if (!KNOWN_VERSIONS.includes(document.format_version)) {
    throw new LibraryReadError(
      `${file}: format_version ${JSON.stringify(document.format_version)} is not one this ` +
        `reader knows (${KNOWN_VERSIONS.join(", ")}): use a newer reader`,
    );
  }
  const problems = schemaProblems(document);
  if (problems.length) {
    throw new LibraryReadError(`${file}: not a valid library: ${problems.slice(0, 5).join("; ")}`);
  }
  return { document, checksum: checksumStatus(document) };
}

/** The entry `id` of a document; throws naming the id when there is none. */
export function entryById(document, id) {
  const entry = document.entries.find((e) => e.id === id);
  if (!entry) throw new LibraryReadError(`no entry ${JSON.stringify(id)} in the library`);
  return entry;
}

/** t mod T in [0, T): a tiny negative t that rounds up to T is the cycle's start. */
function phaseTime(t, T) {
  const tau = ((t % T) + T) % T;
  return tau < T ? tau : 0;
}

/** The Fourier series (a, b: D rows of N+1) at tau seconds, period T: D numbers. */
export function series(a, b, T, tau) {
  return a.map((row, d) => {
    let value = row[0];
    for (let k = 1; k < row.length; k++) {
      const w = (2 * Math.PI * k * tau) / T;
      value += row[k] * Math.cos(w) + b[d][k] * Math.sin(w);
    }
    return value;
  });
}

/**
 * An entry's coordinates at t s from its cycle start (rad; m for pelvis_t*; root in the
 * path frame): q_d(t) = a[d][0] + sum_k (a[d][k] cos(2 pi k tau/T) + b[d][k] sin(2 pi k tau/T))
 * + ramp[d] tau/T, tau = t mod T in [0, T), ramp 0 when the entry stores none.
 */
export function entryAngles(entry, t) {
  const { a, b, ramp } = entry.fourier;
  const tau = phaseTime(t, entry.T);
  const q = series(a, b, entry.T, tau);
  return ramp ? q.map((value, d) => value + (ramp[d] * tau) / entry.T) : q;
}

/**
 * The entry's series seen from tau seconds into its cycle (mocaplib.library.phase
 * .shifted_series): each harmonic k turned by 2 pi k tau / T, the root channels re-anchored
 * so that the path frame starts at the root's pose, the frame's velocities carried along.
 * Returns {a, b, drift: [u_f, u_l, omega]}.
 */
export function shiftedSeries(entry, dofNames, tau) {
  const T = entry.T;
  const [ix, iy, ih] = ROOT_NAMES.map((name) => dofNames.indexOf(name));
  const root = (t) => {
    const q = series(entry.fourier.a, entry.fourier.b, T, t);
    return [q[ix], q[iy], q[ih]];
  };
  const [x0, y0, h0] = root(0);
  const [xt, yt, ht] = root(tau);
  const a = entry.fourier.a.map((row) => row.slice());
  const b = entry.fourier.b.map((row) => row.slice());
  for (let d = 0; d < a.length; d++) {
    for (let k = 0; k < a[d].length; k++) {
      const w = (2 * Math.PI * k * tau) / T;
      const [ak, bk] = [a[d][k], b[d][k]];
      a[d][k] = ak * Math.cos(w) + bk * Math.sin(w);
      b[d][k] = bk * Math.cos(w) - ak * Math.sin(w);
    }
  }
  const turn = h0 - ht;
  const [c, s] = [Math.cos(turn), Math.sin(turn)];
  const shift = [x0 - (c * xt - s * yt), y0 - (s * xt + c * yt)];
  for (const m of [a, b]) {
    for (let k = 0; k < m[ix].length; k++) {
      const [x, y] = [m[ix][k], m[iy][k]];
      m[ix][k] = c * x - s * y;
      m[iy][k] = s * x + c * y;
    }
  }
  a[ix][0] += shift[0];
  a[iy][0] += shift[1];
  a[ih][0] += turn;
  const { u_f_m_s: uf, u_l_m_s: ul, omega_rad_s: omega } = entry.root_drift;
  return {
    a,
    b,
    drift: [c * uf - s * ul + omega * shift[1], s * uf + c * ul - omega * shift[0], omega],
  };
}

/** What blending uses of an entry: its series from its left toe-off, period and drift. */
function blendable(entry, dofNames) {
  if (entry.cycle_start === undefined) {
    const d = entry.root_drift;
    return { a: entry.fourier.a, b: entry.fourier.b, T: entry.T,
             drift: [d.u_f_m_s, d.u_l_m_s, d.omega_rad_s] };
  }
  return { ...shiftedSeries(entry, dofNames, entry.left_toe_off_s), T: entry.T };
}

function sub(p, q) { return [p[0] - q[0], p[1] - q[1], p[2] - q[2]]; }
function add(p, q) { return [p[0] + q[0], p[1] + q[1], p[2] + q[2]]; }
function times(s, p) { return [s * p[0], s * p[1], s * p[2]]; }
function dot(p, q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; }
function cross(p, q) {
  return [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]];
}

/** Barycentric weights (4) of point x in the tetrahedron of vertices p (4 points). */
export function barycentric(p, x) {
  const [a, b, c] = [0, 1, 2].map((i) => sub(p[i], p[3]));
  const rows = [cross(b, c), cross(c, a), cross(a, b)];
  const det = dot(a, rows[0]);
  const w3 = rows.map((row) => dot(times(1 / det, row), sub(x, p[3])));
  return [...w3, 1 - (w3[0] + w3[1] + w3[2])];
}

/**
 * A command [v, omega, v_l] with a pure side-step put on the cone |v_l| = v: v_l = ±v when
 * v > 0 and cos(2°) v <= |v_l| <= v (1 + 1e-9); any other command unchanged.
 */
export function ontoCone([v, omega, vl]) {
  const lateral = Math.abs(vl);
  const side = v > 0 && lateral >= Math.cos(SIDEWAYS_TOLERANCE) * v && lateral <= v * (1 + 1e-9);
  return side ? [v, omega, Math.sign(vl) * v] : [v, omega, vl];
}

/**
 * A command [v, omega, v_l] on the frontal axes [v_f, omega, v_l]: v_f = +sqrt(v² − v_l²)
 * (0 when |v_l| > v), as mocaplib.library.cells.to_frontal.
 */
export function toFrontal([v, omega, vl]) {
  return [Math.sqrt(Math.max(v * v - vl * vl, 0)), omega, vl];
}

/**
 * Of tetrahedra (rows of 4 indices into points), the one holding x whose smallest weight is
 * largest (the first of equals), when that weight is >= -tol: {simplex, weights}, else null.
 */
function locate(simplices, points, x, tol) {
  let best = null;
  for (const simplex of simplices) {
    const w = barycentric(simplex.map((i) => points[i]), x);
    const worst = Math.min(...w);
    if (best === null || worst > best.worst) best = { simplex, w, worst };
  }
  return best !== null && best.worst >= -tol ? { simplex: best.simplex, weights: best.w } : null;
}

/** The triangles (sorted index triples, sorted) that only one of the tetrahedra has. */
function boundary(simplices) {
  const count = new Map();
  for (const s of simplices) {
    for (const drop of [0, 1, 2, 3]) {
      const face = s.filter((_, k) => k !== drop).sort((i, j) => i - j);
      const key = face.join(",");
      count.set(key, (count.get(key) ?? 0) + 1);
    }
  }
  return [...count].filter(([, n]) => n === 1).map(([key]) => key.split(",").map(Number))
    .sort((f, g) => f[0] - g[0] || f[1] - g[1] || f[2] - g[2]);
}

/**
 * The closest point of triangle (A, B, C) to p and its squared distance: the projection onto
 * the triangle's plane when it falls inside the triangle, else the closest point of its edges.
 */
export function closestOnTriangle(p, [A, B, C]) {
  const n = cross(sub(B, A), sub(C, A));
  const proj = sub(p, times(dot(sub(p, A), n) / dot(n, n), n));
  const edges = [[A, B], [B, C], [C, A]];
  if (edges.every(([U, V]) => dot(cross(sub(V, U), sub(proj, U)), n) >= 0)) {
    return { point: proj, d2: dot(sub(p, proj), sub(p, proj)) };
  }
  let best = { point: null, d2: Infinity };
  for (const [U, V] of edges) {
    const e = sub(V, U);
    const s = Math.min(Math.max(dot(sub(p, U), e) / dot(e, e), 0), 1);
    const c = add(U, times(s, e));
    const d2 = dot(sub(p, c), sub(p, c));
    if (d2 < best.d2) best = { point: c, d2 };
  }
  return best;
}

/** Largest signed distance of x beyond the hull triangles' planes (oriented outwards). */
function outsidePlanes(points, hull, x) {
  const centroid = times(1 / points.length, points.reduce(add, [0, 0, 0]));
  let most = -Infinity;
  for (const [i, j, k] of hull) {
    const [A, B, C] = [points[i], points[j], points[k]];
    let n = cross(sub(B, A), sub(C, A));
    n = times(1 / Math.sqrt(dot(n, n)), n);
    if (dot(n, sub(centroid, A)) > 0) n = times(-1, n);
    most = Math.max(most, dot(n, sub(x, A)));
  }
  return most;
}

/**
 * The stored control space of a document: entries (by row of tetrahedra.ids), their
 * normalised points as stored (raw), with side-steps on the cone (cone) and those on the
 * frontal axes (frontal), the gait cells ({gait, simplices, boundary, frontal: the cell's
 * frontal tetrahedra {simplices, boundary} or null}, walks first) and the hull of all the
 * entries.
 */
export function storedCells(document) {
  const stored = document.control_space.tetrahedra;
  if (stored === undefined) {
    throw new LibraryReadError("the library stores no tetrahedra: its entries span no 3-D " +
                               "control space (mocaplib validate says why)");
  }
  if (document.format_version < GAIT_CELLS_VERSION) {
    throw new LibraryReadError(
      `a format_version ${document.format_version} library stores the tetrahedra of all its ` +
        `entries, walks and runs together, not its gait cells: build it again with mocaplib ` +
        `build (format_version ${GAIT_CELLS_VERSION})`);
  }
  const scale = document.control_space.scale;
  const entries = stored.ids.map((id) => entryById(document, id));
  const normalised = (p) => p.map((value, i) => value / scale[i]);
  const raw = entries.map((e) => normalised([e.v, e.omega, e.v_l]));
  const cone = entries.map((e) => normalised(ontoCone([e.v, e.omega, e.v_l])));
  const frontal = entries.map((e) => normalised(toFrontal(ontoCone([e.v, e.omega, e.v_l]))));
  const cells = [];
  stored.simplices.forEach((simplex, s) => {
    const gait = stored.gaits[s];
    let cell = cells.find((c) => c.gait === gait);
    if (!cell) cells.push((cell = { gait, simplices: [], frontal: null }));
    cell.simplices.push(simplex);
  });
  (stored.frontal_simplices ?? []).forEach((simplex, s) => {
    const cell = cells.find((c) => c.gait === stored.frontal_gaits[s]);
    if (cell.frontal === null) cell.frontal = { simplices: [] };
    cell.frontal.simplices.push(simplex);
  });
  for (const cell of cells) {
    cell.boundary = boundary(cell.simplices);
    if (cell.frontal !== null) cell.frontal.boundary = boundary(cell.frontal.simplices);
  }
  return { scale, entries, raw, cone, frontal, cells, hull: stored.hull };
}

/** The nearest point of the triangles `faces` (rows of 3 indices into points) to x. */
function nearestOnFaces(faces, points, x) {
  let best = null;
  for (const face of faces) {
    const c = closestOnTriangle(x, face.map((i) => points[i]));
    if (best === null || c.d2 < best.d2) best = c;
  }
  return best;
}

/**
 * The entries and weights of a point served by `cell` (SI, on the cone): its barycentric
 * coordinates on the frontal axes (normalised) in the cell's frontal tetrahedra, or at the
 * nearest point of their boundary when it lies outside them; the tetrahedron `found` in the
 * cell's own tetrahedra when the cell has no frontal ones.
 */
function weighOnFrontalAxes(space, cell, served, found) {
  if (cell.frontal === null) return found;
  const f = toFrontal(served).map((value, i) => value / space.scale[i]);
  return locate(cell.frontal.simplices, space.frontal, f, WEIGHT_TOLERANCE)
    ?? locate(cell.frontal.simplices, space.frontal,
              nearestOnFaces(cell.frontal.boundary, space.frontal, f).point,
              BOUNDARY_WEIGHT_TOLERANCE)
    ?? found;
}

/**
 * Where a command [v, omega, v_l] (SI) is blended, as `mocaplib query` answers it: its point
 * (side-steps on the cone, / scale) in the tetrahedron of the cells (of `gait` only, when
 * given) whose smallest weight is largest (inside when >= -1e-9); else the nearest point of
 * the nearest cell, served there when within 1e-6 of it (inside) or inside the hull of all
 * the entries (clamped: between the cells), else outside. The weights of a served point are
 * computed on the frontal axes (weighOnFrontalAxes). Returns {inside, gait, clamped,
 * entries (ids), weights (clipped at 0, sum 1), nearest (SI), distance (normalised)}.
 */
export function query(document, command, gait = null) {
  if (command.length !== 3 || !command.every(Number.isFinite)) {
    throw new LibraryReadError(`a command is three finite numbers, got ${JSON.stringify(command)}`);
  }
  const space = storedCells(document);
  const cells = gait === null ? space.cells : space.cells.filter((c) => c.gait === gait);
  if (!cells.length) {
    throw new LibraryReadError(`the control space has no ${gait} cell to blend in (cells: ` +
                               `${space.cells.map((c) => c.gait).join(", ") || "none"})`);
  }
  const x = command.map((value, i) => value / space.scale[i]);
  const onCone = ontoCone(command).map((value, i) => value / space.scale[i]);
  const cellOf = new Map(cells.flatMap((c) => c.simplices.map((s) => [s, c])));
  const answer = (located, cell, point, distance, clamped) => {
    const served = point === onCone ? ontoCone(command)
      : point.map((value, i) => value * space.scale[i]);
    const found = weighOnFrontalAxes(space, cell, served, located);
    const clipped = found.weights.map((w) => Math.max(w, 0));
    const total = clipped.reduce((s, w) => s + w, 0);
    return {
      inside: true, gait: cell.gait, clamped,
      entries: found.simplex.map((i) => space.entries[i].id),
      weights: clipped.map((w) => w / total),
      nearest: clamped ? point.map((value, i) => value * space.scale[i]) : command.slice(),
      distance: clamped ? distance : 0,
    };
  };
  const direct = locate(cells.flatMap((c) => c.simplices), space.cone, onCone, WEIGHT_TOLERANCE);
  if (direct !== null) return answer(direct, cellOf.get(direct.simplex), onCone, 0, false);
  let near = null;
  for (const cell of cells) {
    const best = nearestOnFaces(cell.boundary, space.cone, onCone);
    const distance = Math.sqrt(best.d2);
    if (near === null || distance < near.distance) near = { cell, point: best.point, distance };
  }
  const inHull = outsidePlanes(space.raw, space.hull, x) <= HULL_TOLERANCE;
  const found = near.distance <= HULL_TOLERANCE || inHull
    ? locate(near.cell.simplices, space.cone, near.point, BOUNDARY_WEIGHT_TOLERANCE) : null;
  if (found !== null) {
    return answer(found, near.cell, near.point, near.distance,
                  near.distance > HULL_TOLERANCE);
  }
  return {
    inside: false, gait: near.cell.gait, clamped: false,
    nearest: near.point.map((value, i) => value * space.scale[i]), distance: near.distance,
  };
}

/**
 * The answer of query() with, when the command is served, the blend: the weights of its
 * entries on their coefficients (from each entry's left toe-off), periods and drift
 * velocities: {..., T, a, b, drift}.
 */
export function blend(document, command, gait = null) {
  const answer = query(document, command, gait);
  if (!answer.inside) return answer;
  const dofNames = document.skeleton.dof_names;
  const parts = answer.entries.map((id) => blendable(entryById(document, id), dofNames));
  const { weights } = answer;
  const mix = (get) => get(parts[0]).map((row, d) => row.map((_, k) =>
    parts.reduce((s, part, j) => s + weights[j] * get(part)[d][k], 0)));
  return {
    ...answer,
    T: parts.reduce((s, part, j) => s + weights[j] * part.T, 0),
    a: mix((part) => part.a),
    b: mix((part) => part.b),
    drift: [0, 1, 2].map((i) => parts.reduce((s, part, j) => s + weights[j] * part.drift[i], 0)),
  };
}

/** Every number of a JSON value, depth first (for checking how numbers read back). */
export function numbers(value, out = []) {
  if (Array.isArray(value)) value.forEach((item) => numbers(item, out));
  else if (value !== null && typeof value === "object") {
    Object.values(value).forEach((item) => numbers(item, out));
  } else if (typeof value === "number") out.push(value);
  return out;
}

function main(argv) {
  const args = { queries: [], phases: 8, gait: null };
  for (let i = 0; i < argv.length; i++) {
    if (argv[i] === "--phases") args.phases = Number(argv[++i]);
    else if (argv[i] === "--gait") args.gait = argv[++i];
    else if (argv[i] === "--query") {
      args.queries.push(argv.slice(i + 1, i + 4).map(Number));
      i += 3;
    } else args.library = argv[i];
  }
  if (!args.library) {
    process.stderr.write("usage: node mocaplib-library.js LIBRARY.json [--phases N] " +
                         "[--gait walk|run] [--query V OMEGA VL]...\n");
    return 2;
  }
  try {
    const { document, checksum } = readLibrary(args.library);
    const angles = {};
    for (const entry of document.entries) {
      angles[entry.id] = Array.from({ length: args.phases },
                                    (_, j) => entryAngles(entry, (entry.T * j) / args.phases));
    }
    const blends = args.queries.map((command) => blend(document, command, args.gait));
    process.stdout.write(JSON.stringify({ checksum, angles, blends }) + "\n");
    return 0;
  } catch (error) {
    if (!(error instanceof LibraryReadError)) throw error;
    process.stderr.write(`error: ${error.message}\n`);
    return 1;
  }
}

if (process.argv[1] && path.resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
  process.exitCode = main(process.argv.slice(2));
}
