// Reference reader of mocaplib motion library files: docs/library-format.md as code.
//
// readLibrary(path)            parse, refuse an unknown format_version, validate against the
//                              shipped JSON Schema (Ajv, draft 2020-12, strict), verify the
//                              content checksum (RFC 8785 / JCS + SHA-256)
// entryAngles(entry, t)        an entry's coordinates at t seconds (the documented formula,
//                              ramp included; periodic on [0, T))
// blend(library, command)      the entries and barycentric weights of a velocity command
//                              (v m/s, omega rad/s, v_l m/s) and the blended series, as
//                              `mocaplib query` computes them, in the tetrahedra the file
//                              stores (control_space.tetrahedra)
//
// Run as a script: node mocaplib-library.js LIBRARY.json [--phases N] [--query V OMEGA VL]...
//   prints a JSON report (used by the Python tests).
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
export const KNOWN_VERSIONS = [1, 2, 3];
/** Versions whose checksum is Python-printed JSON, which only Python reproduces. */
export const PYTHON_CHECKSUM_VERSIONS = [1, 2];
/** Root channels (pelvis_tx, pelvis_ty, pelvis_rotation) by name, for re-anchoring. */
const ROOT_NAMES = ["pelvis_tx", "pelvis_ty", "pelvis_rotation"];
/** A query within this of a face (normalised units) counts inside, as in Python's locate. */
const INSIDE_TOLERANCE = 1e-9;

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
function dot(p, q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; }
function cross(p, q) {
  return [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]];
}

/** Barycentric weights (4) of point x in the tetrahedron of vertices p (4 points). */
export function barycentric(p, x) {
  const [a, b, c] = [0, 1, 2].map((i) => sub(p[i], p[3]));
  const rows = [cross(b, c), cross(c, a), cross(a, b)];
  const det = dot(a, rows[0]);
  const w3 = rows.map((row) => dot(row, sub(x, p[3])) / det);
  return [...w3, 1 - (w3[0] + w3[1] + w3[2])];
}

/**
 * Blend a velocity command [v, omega, v_l] (SI): the tetrahedron holding its normalised point
 * (value / control_space.scale), the one whose smallest weight is largest; weights clipped at
 * 0 and summing to 1; coefficients, period and drift velocities blended with them. Returns
 * {inside: false} outside the control space.
 */
export function blend(document, command) {
  const tetrahedra = document.control_space.tetrahedra;
  if (tetrahedra === undefined) {
    throw new LibraryReadError("the library stores no tetrahedra: its entries span no 3-D " +
                               "control space (or it was written before format_version 3)");
  }
  if (command.length !== 3 || !command.every(Number.isFinite)) {
    throw new LibraryReadError(`a command is three finite numbers, got ${JSON.stringify(command)}`);
  }
  const scale = document.control_space.scale;
  const entries = tetrahedra.ids.map((id) => entryById(document, id));
  const point = (e) => [e.v / scale[0], e.omega / scale[1], e.v_l / scale[2]];
  const x = command.map((value, i) => value / scale[i]);
  let best = null;
  for (const simplex of tetrahedra.simplices) {
    const w = barycentric(simplex.map((i) => point(entries[i])), x);
    const worst = Math.min(...w);
    if (best === null || worst > best.worst) best = { simplex, w, worst };
  }
  if (best === null || best.worst < -INSIDE_TOLERANCE) return { inside: false };
  const clipped = best.w.map((w) => Math.max(w, 0));
  const total = clipped.reduce((s, w) => s + w, 0);
  const weights = clipped.map((w) => w / total);
  const dofNames = document.skeleton.dof_names;
  const parts = best.simplex.map((i) => blendable(entries[i], dofNames));
  const mix = (get) => get(parts[0]).map((row, d) => row.map((_, k) =>
    parts.reduce((s, part, j) => s + weights[j] * get(part)[d][k], 0)));
  return {
    inside: true,
    entries: best.simplex.map((i) => entries[i].id),
    weights,
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
  const args = { queries: [], phases: 8 };
  for (let i = 0; i < argv.length; i++) {
    if (argv[i] === "--phases") args.phases = Number(argv[++i]);
    else if (argv[i] === "--query") {
      args.queries.push(argv.slice(i + 1, i + 4).map(Number));
      i += 3;
    } else args.library = argv[i];
  }
  if (!args.library) {
    process.stderr.write("usage: node mocaplib-library.js LIBRARY.json [--phases N] " +
                         "[--query V OMEGA VL]...\n");
    return 2;
  }
  try {
    const { document, checksum } = readLibrary(args.library);
    const angles = {};
    for (const entry of document.entries) {
      angles[entry.id] = Array.from({ length: args.phases },
                                    (_, j) => entryAngles(entry, (entry.T * j) / args.phases));
    }
    const blends = args.queries.map((command) => blend(document, command));
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
