// The Draco page's worker (web/draco.html, docs/BROWSER.md): downloads the
// model's whole Draco file (/models/NAME/draco, full access only: a preview
// model's is refused without a token), decodes it with Draco's own
// WebAssembly decoder (npm draco3d's draco_decoder_nodejs.js and
// draco_decoder.wasm, which make wasm copies beside the pages; the same file
// runs in a browser's worker), and hands the page float positions,
// per-vertex normals (area-weighted means of the triangles', as the view
// decoder's ms_web_view_normals) and 32-bit triangle corners, transferred.
// Messages in: {name, token}; out: {type: 'mesh', ...} or {type: 'error',
// message} (one line).
'use strict';

const DECODER = 'draco_decoder_nodejs.js';
const SILENCE_MS = 10000;   // a download with nothing heard for this long is abandoned

function capital(text) {
  return text.charAt(0).toUpperCase() + text.slice(1);
}

// The whole answer to path (relative to this script), or an Error of one line:
// the server's own for an error answer.
async function download(path, token) {
  const headers = token ? { Authorization: 'Bearer ' + token } : {};   // never in the URL
  const abort = new AbortController();
  let timer = setTimeout(() => abort.abort(), SILENCE_MS);
  const heard = () => {
    clearTimeout(timer);
    timer = setTimeout(() => abort.abort(), SILENCE_MS);
  };
  let answer;
  const pieces = [];
  let length = 0;
  try {
    answer = await fetch(new URL(path, self.location.href).href, { headers, signal: abort.signal });
    heard();
    const reader = answer.body.getReader();
    for (;;) {
      const { done, value } = await reader.read();
      if (done)
        break;
      heard();
      pieces.push(value);
      length += value.length;
    }
  } catch (e) {
    throw new Error((abort.signal.aborted ? 'The server stopped answering' : 'The server cannot be reached') +
                    ' (/' + path.replace(/^(\.\.\/)+/, '') + ')');
  } finally {
    clearTimeout(timer);
  }
  const bytes = new Uint8Array(length);
  let at = 0;
  for (const piece of pieces) {
    bytes.set(piece, at);
    at += piece.length;
  }
  if (answer.status !== 200) {
    const text = new TextDecoder().decode(bytes).trim().replace(/^error: /, '');
    throw new Error(capital(text || 'the server answered ' + answer.status) + ' (/' +
                    path.replace(/^(\.\.\/)+/, '') + ')');
  }
  return bytes;
}

// Draco's decoder module (its script loaded into this worker), compiling.
function loadDecoder() {
  try {
    importScripts(DECODER);
  } catch (e) {
    return Promise.reject(new Error('Draco\'s decoder is not on this server (' + DECODER +
                                    ' of npm draco3d: scripts/install-deps, then make wasm)'));
  }
  return new Promise((resolve, reject) => {
    const settings = {
      onAbort: what => reject(new Error('Draco\'s decoder failed to start (draco_decoder.wasm: ' +
                                        String(what || 'aborted').split('\n')[0] + ')')),
    };
    /* global DracoDecoderModule */
    DracoDecoderModule(settings).then(module => {
      delete module.then;      // an Emscripten module is a thenable: resolve it as a plain object
      resolve(module);
    }, e => reject(new Error('Draco\'s decoder failed to start: ' + e)));
  });
}

// The decoded mesh: {positions, triangles} as typed arrays of their own.
function decode(D, bytes) {
  const decoder = new D.Decoder(), mesh = new D.Mesh();
  try {
    const data = new Int8Array(bytes.buffer, bytes.byteOffset, bytes.length);
    if (decoder.GetEncodedGeometryType(data) !== D.TRIANGULAR_MESH)
      throw new Error('The Draco file holds no triangle mesh');
    const status = decoder.DecodeArrayToMesh(data, data.length, mesh);
    if (!status.ok() || mesh.ptr === 0)
      throw new Error('The Draco file does not decode: ' + status.error_msg());
    const faces = mesh.num_faces(), points = mesh.num_points();
    const attribute = decoder.GetAttribute(mesh, decoder.GetAttributeId(mesh, D.POSITION));
    if (!attribute || attribute.ptr === 0 || attribute.num_components() !== 3)
      throw new Error('The Draco file has no 3D positions');
    const triangleBytes = faces * 12, positionBytes = points * 12;
    const t = D._malloc(Math.max(triangleBytes, 4)), p = D._malloc(Math.max(positionBytes, 4));
    try {
      if (!t || !p || !decoder.GetTrianglesUInt32Array(mesh, triangleBytes, t) ||
          !decoder.GetAttributeDataArrayForAllPoints(mesh, attribute, D.DT_FLOAT32, positionBytes, p))
        throw new Error('The Draco file\'s mesh cannot be read out of the decoder');
      return { triangles: new Uint32Array(D.HEAPU8.buffer, t, faces * 3).slice(),
               positions: new Float32Array(D.HEAPU8.buffer, p, points * 3).slice() };
    } finally {
      D._free(t);
      D._free(p);
    }
  } finally {
    D.destroy(mesh);
    D.destroy(decoder);
  }
}

// Per vertex the sum of its triangles' cross products (area-weighted; the
// shader normalises), and the bounds.
function normalsAndBounds(positions, triangles) {
  const normals = new Float32Array(positions.length);
  for (let i = 0; i < triangles.length; i += 3) {
    const a = 3 * triangles[i], b = 3 * triangles[i + 1], c = 3 * triangles[i + 2];
    const ux = positions[b] - positions[a], uy = positions[b + 1] - positions[a + 1], uz = positions[b + 2] - positions[a + 2];
    const vx = positions[c] - positions[a], vy = positions[c + 1] - positions[a + 1], vz = positions[c + 2] - positions[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    for (const k of [a, b, c]) {
      normals[k] += nx;
      normals[k + 1] += ny;
      normals[k + 2] += nz;
    }
  }
  const bounds = [Infinity, Infinity, Infinity, -Infinity, -Infinity, -Infinity];
  for (let i = 0; i < positions.length; i += 3)
    for (let a = 0; a < 3; ++a) {
      bounds[a] = Math.min(bounds[a], positions[i + a]);
      bounds[a + 3] = Math.max(bounds[a + 3], positions[i + a]);
    }
  return { normals, bounds };
}

onmessage = async e => {
  const { name, token } = e.data;
  const started = performance.now();
  try {
    // the download starts first; the decoder's script and module load meanwhile
    const file = download('../models/' + encodeURIComponent(name) + '/draco', token);
    file.catch(() => {});
    let ready = 0;
    const decoder = loadDecoder().then(module => { ready = performance.now(); return module; });
    decoder.catch(() => {});
    const bytes = await file;
    const fetched = performance.now();
    const D = await decoder;
    const { positions, triangles } = decode(D, bytes);
    const decoded = performance.now();
    if (!triangles.length)
      throw new Error('The Draco file holds no triangle');
    const { normals, bounds } = normalsAndBounds(positions, triangles);
    const timing = { download: (fetched - started) / 1000, decoder: (ready - started) / 1000,
                     decode: (decoded - Math.max(fetched, ready)) / 1000,
                     normals: (performance.now() - decoded) / 1000 };
    postMessage({ type: 'mesh', positions, normals, triangles, bounds, bytes: bytes.length, timing },
                [positions.buffer, normals.buffer, triangles.buffer]);
  } catch (err) {
    postMessage({ type: 'error', message: String(err.message || err).split('\n')[0] });
  }
};
