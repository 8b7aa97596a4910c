// The decoding worker of the viewer page (docs/BROWSER.md): the view decoder
// of the C sources, compiled to WebAssembly (make wasm: meshstream.js and
// meshstream.wasm, the interface of client/web/ms_web_view.h), fed over the
// HTTP side door. Messages in: {type: 'start', name, token, camera, culled, memory},
// {type: 'camera', camera} (a new camera: the loop plans again),
// {type: 'sections', planes} (a b c d each: ms_web_view_sections; the page
// sends a camera after them), {type: 'cast', rays: [{origin, direction,
// tMin, tNear}], ...} (ms_web_view_cast on the last mesh; answered at once
// with the message's fields and hits: [{point, t, bits, step, modelBits} or
// null]), {type: 'refine', seq, points: [{point, direction}]} (each point
// refined to full precision by a probe, then cast: answered point by point).
// Out: {type: 'alive'} (first: the worker runs), {type: 'box'}, {type: 'progress'},
// {type: 'mesh'} (positions, normals,
// triangles and a colour model's colours, transferred), {type: 'complete'}, {type: 'cast'},
// {type: 'error', message}.
'use strict';

// Said first: the page makes its WebGL context once this worker runs
// (boot.js), since making it holds the page's thread that a worker's start
// waits for.
postMessage({ type: 'alive' });

// The module, beside this file: in a cross-origin isolated page (meshserve
// sends COOP and COEP; SharedArrayBuffer exists) the build with pthreads,
// meshstream-mt, which decodes on several threads (ms_web_view_threads);
// elsewhere (a static export's server without those headers, a frame of a
// page that is not isolated) the single-threaded one. Its loader comes
// after this file's code in the site's worker.js (make wasm), or is read
// (importScripts) once the first message has sent the model's first
// requests (boot.js's prefetch); its WebAssembly comes
// compiled from the page (boot.js's 'module' message: fetched and compiled
// while this worker started), or, where the page could not, is fetched and
// compiled here.
let fromPage = null;
const pageModule = new Promise(resolve => { fromPage = resolve; });
function instantiate(file, imports, receive) {
  pageModule.then(m => m && m.file === file && m.module ? m.module
    : fetch(here(file)).then(r => r.arrayBuffer()).then(bytes => WebAssembly.compile(bytes)))
    .then(module => WebAssembly.instantiate(module, imports).then(instance => receive(instance, module)))
    .catch(e => fail('the decoder cannot start: ' + (e.message || String(e))));
  return {};
}
const here = file => new URL(file, self.location.href).href;
let threaded = self.crossOriginIsolated === true && typeof SharedArrayBuffer === 'function' &&
               new URL(self.location.href).searchParams.get('threads') !== '0';   // boot.js's #threads=0
let modulePromise = null;
function loadModule() {
  if (modulePromise)
    return modulePromise;
  // make wasm appends both loaders to this file (the Makefile's site
  // worker.js): one request where the loader was a second, read only once
  // this one ran; a worker.js served as it is in web/ reads them here
  if (threaded && typeof createMeshstreamThreads !== 'function') {
    try {
      importScripts('meshstream-mt.js');
    } catch (e) {
      threaded = false;           // a site built before the threaded module
    }
  }
  if (!threaded && typeof createMeshstream !== 'function')
    importScripts('meshstream.js');
  mark('loader');
  modulePromise = threaded
    ? createMeshstreamThreads({
        locateFile: file => here(file === 'meshstream-mt.worker.js' ? 'meshstream-mt-worker.js' : file),
        mainScriptUrlOrBlob: here('meshstream-mt.js'),
        instantiateWasm: (imports, receive) => instantiate('meshstream-mt.wasm', imports, receive) })
    : createMeshstream({ locateFile: here,
                         instantiateWasm: (imports, receive) => instantiate('meshstream.wasm', imports, receive) });
  return modulePromise;
}
// Helper threads for decoding: the cores less this one, at most 2. They are
// made once the first picture is posted (each is a worker of its own that
// loads the module: not before the first pixels), and join the plans from
// when they have started.
const helpers = () => threaded ? Math.max(0, Math.min((navigator.hardwareConcurrency || 1) - 1, 2)) : 0;
function startHelpers() {
  if (timing.threads === 1 && helpers() > 0)
    timing.threads = 1 + M._ms_web_view_threads(view, helpers());
}

// The module's memory: with threads it is shared and grows from any thread,
// so the views are made afresh from its current buffer at each use (a view
// made before a helper grew it would miss the new part).
const heap = () => (M.wasmMemory ? M.wasmMemory.buffer : M.HEAPU8.buffer);
const U8 = () => new Uint8Array(heap());
const U32 = () => new Uint32Array(heap());

// Where the model's files are, relative to the site's root (the folder above
// web/): meshserve's side door, or a static export (meshexport --web-dir),
// whose index is a file of its own and whose cells are whole files, read by
// byte ranges (any web server honours Range; a query string it ignores).
// The index comes by subtree, as the native client reads it: its head (the
// header and the root subtree) at once, each further subtree as the plans
// ask (docs/ARCHIVE.md, "Subtrees"); the whole index only where the head is
// missing (404: a site exported before the head was).
const ROOT = new URL('../', self.location.href);
const LAYOUTS = {
  door: {
    catalogue: name => 'catalog?limit=1000&q=' + encodeURIComponent(name),
    index: name => 'models/' + encodeURIComponent(name),
    head: name => 'models/' + encodeURIComponent(name) + '/head',
    subtree: (name, id) => 'models/' + encodeURIComponent(name) + '/subtrees/' + id,
    // several subtrees at once (fetchSubtrees)
    subtrees: (name, ids) => 'models/' + encodeURIComponent(name) + '/subtrees?ids=' + ids.join(','),
    cell: (name, cell, bits) => 'models/' + encodeURIComponent(name) + '/cells/' + cell +
                                '/geometry' + (bits === null ? '' : '?bits=' + bits),
    // several cells at once (fetchCells): {cell, bits, from} each
    cells: (name, items) => 'models/' + encodeURIComponent(name) + '/cells?geometry=' +
                            items.map(it => it.cell + '.' + it.bits + '.' + it.from).join(','),
    colour: (name, cell, bits) => 'models/' + encodeURIComponent(name) + '/cells/' + cell + '/colour?bits=' + bits,
    ranged: false,      // the server cuts the prefix at ?bits=
  },
  static: {
    catalogue: () => 'catalog.json',
    index: name => 'models/' + encodeURIComponent(name) + '.index',
    head: name => 'models/' + encodeURIComponent(name) + '.head',
    subtree: (name, id) => 'models/' + encodeURIComponent(name) + '/subtrees/' + id,
    cell: (name, cell) => 'models/' + encodeURIComponent(name) + '/cells/' + cell + '/geometry',
    colour: (name, cell) => 'models/' + encodeURIComponent(name) + '/cells/' + cell + '/colour',
    ranged: true,       // the prefix is a byte range of the whole file
  },
};
let layout = LAYOUTS.door;

// Cell fetches at a time: more than the browser's 6 connections to a host,
// so that its network keeps the link busy while the worker decodes (a long
// decode cannot issue requests; what waits in the browser's queue goes on).
const IN_FLIGHT = 64;
// Cells in one request of the side door's cells route (fetchCells): a level
// of the cut in a round trip or two, where one request a cell kept each of
// a browser's six connections busy a round trip a cell.
const BATCH_CELLS = 16;
// Subtrees in one request of the side door's subtrees route (fetchSubtrees):
// the server's most.
const BATCH_SUBTREES = 64;
const SILENCE_MS = 10000;   // a request with nothing heard for this long is abandoned
const PLAN_MAX = 1024;      // cells listed by one plan
const SHOW_EVERY_MS = 200;       // within a round, how often what came is decoded and shown
const STITCH_SHARE = 5;          // (at least this many times the last stitch's time apart),
const DECODE_EVERY_BYTES = 32768; // or after how many bytes
const FIRST_LOOK = [16, 64, 256, 4096]; // the first round's tolerances, times the camera's
const FIRST_LOOK_BYTES = 32768;         // and the most that round may fetch
const HOME_BITS = 5;        // the root's bits for the home camera's bounds and first picture
const ERROR_SIZE = 520;     // sizeof(ms_error), with room

let M = null;               // the WebAssembly module
let view = 0;               // ms_web_view *

function fail(message) {
  postMessage({ type: 'error', message });
}

function lastError(v) {
  return M.UTF8ToString(M._ms_web_view_error(v || view));
}

// A GET whose answer is read whole: {status, bytes}. Any failure of the
// network, before or during the body, is one error naming what was asked;
// an error answer's is the server's own line; 429 (the request rate limit)
// is retried after its Retry-After, four times at most.
// ticket (optional): {cancel: AbortController, started: false}: the caller's
// to cancel the request while it waits for its answer's head (a new camera,
// below); started is set once the head came. A cancelled request throws an
// error whose `cancelled` is true.
async function get(path, token, extra, ticket) {
  const url = new URL(path, ROOT).href;
  const headers = Object.assign({}, extra || {});
  if (token)
    headers.Authorization = 'Bearer ' + token;   // never in the URL
  let answer, bytes;
  for (let attempt = 0; ; ++attempt) {
    // A silent server (or a connection the browser keeps waiting on after
    // its peer went away) must not leave the page loading for ever: the
    // request is abandoned after SILENCE_MS without a byte.
    const abort = new AbortController();
    let timer = setTimeout(() => abort.abort(), SILENCE_MS);
    const heard = () => {
      clearTimeout(timer);
      timer = setTimeout(() => abort.abort(), SILENCE_MS);
    };
    const cancel = () => abort.abort();
    if (ticket)
      ticket.cancel.signal.addEventListener('abort', cancel);
    try {
      if (ticket && ticket.cancel.signal.aborted)
        throw new Error('cancelled');
      answer = await fetch(url, { headers, cache: 'default', signal: abort.signal });
      if (ticket)
        ticket.started = true;
      heard();
      bytes = await readBody(answer, heard);
    } catch (e) {
      if (ticket && ticket.cancel.signal.aborted) {
        const c = new Error('cancelled (/' + path.replace(/\?.*/, '') + ')');
        c.cancelled = true;
        throw c;
      }
      throw new Error((abort.signal.aborted ? 'the server stopped answering' : 'the server cannot be reached') +
                      ' (/' + path.replace(/\?.*/, '') + ')');
    } finally {
      clearTimeout(timer);
      if (ticket)
        ticket.cancel.signal.removeEventListener('abort', cancel);
    }
    // the server's request rate limit: wait as it says, a few times
    if (answer.status !== 429 || attempt === 4)
      break;
    const wait = Math.min(Number(answer.headers.get('Retry-After')) || 1, 10);
    await new Promise(resolve => setTimeout(resolve, wait * 1000));
  }
  if (answer.status !== 200 && answer.status !== 206) {
    const text = new TextDecoder().decode(bytes).trim().replace(/^error: /, '');
    const e = new Error(text || ('the server answered ' + answer.status));
    e.status = answer.status;
    throw e;
  }
  return { status: answer.status, bytes, headers: answer.headers };
}

// An answer's body, whole; heard() at each piece that comes.
async function readBody(answer, heard) {
  if (!answer.body)
    return new Uint8Array(await answer.arrayBuffer());
  const reader = answer.body.getReader(), pieces = [];
  let length = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done)
      break;
    heard();
    pieces.push(value);
    length += value.length;
  }
  if (pieces.length === 1)
    return pieces[0];
  const bytes = new Uint8Array(length);
  let at = 0;
  for (const piece of pieces) {
    bytes.set(piece, at);
    at += piece.length;
  }
  return bytes;
}

function withHeap(bytes, fn) {
  const p = M._malloc(Math.max(bytes.length, 1));
  if (!p)
    throw new Error('out of memory in the WebAssembly module');
  try {
    U8().set(bytes, p);
    return fn(p);
  } finally {
    M._free(p);
  }
}

// A view over the index: its head (byHead; the subtrees to come) or the whole blob.
function openIndex(blob, name, byHead) {
  const err = M._malloc(ERROR_SIZE), out = M._malloc(4);
  const nameBytes = new TextEncoder().encode(name + '\0');
  const open = byHead ? M._ms_web_view_new_head : M._ms_web_view_new;
  try {
    const st = withHeap(nameBytes, namePtr =>
      withHeap(blob, blobPtr => open(blobPtr, blob.length, namePtr, out, err)));
    if (st !== 0)
      throw new Error('the model\'s index cannot be read: ' + M.UTF8ToString(err + 4));
    return U32()[out >> 2];
  } finally {
    M._free(err);
    M._free(out);
  }
}

function setCamera(c) {
  const p = M._malloc(9 * 8);
  const d = new Float64Array(heap(), p, 9);
  d.set([...c.position, ...c.target, ...c.up]);
  const st = M._ms_web_view_camera(view, p, p + 24, p + 48, c.fovy, c.width, c.height,
                                   0, 0, c.tolerance);
  M._free(p);
  if (st !== 0)
    throw new Error('bad camera: ' + lastError());
  // the geometry under APO (web/worker-apo.js), once a camera has wanted it
  if (apoWanted(c) || apoLoaded) {
    loadApo();
    apoCamera(c);
  }
}

// The APO part (web/worker-apo.js: apoCamera, apoRound), read the first time
// a camera wants APO: a view drawn without it (the default 1 px tolerance,
// --shading geometry) never waits for its script, which the first pixels
// used to wait for (one more request before the decoder's start). Until
// then the view selects as without APO.
let apoLoaded = false;
function loadApo() {
  if (!apoLoaded) {
    importScripts('worker-apo.js');
    apoLoaded = timing.apoLoaded = true;
  }
}
// px: meshview's --apo-min-tolerance default (MS_CORE_APO_MIN_TOLERANCE_DEFAULT):
// at a finer geometric tolerance the chunks add bytes and no picture
// (docs/ACCURACY.md, "Where APO pays"), so none is fetched
const APO_MIN_TOLERANCE = 2;
// Whether camera c's view fetches and draws APO: its shading asks for it and
// its geometry is coarse enough to gain from it.
const apoWanted = c => !!c.apo && c.tolerance >= APO_MIN_TOLERANCE;

// Fetches what the cell lacks of its payload prefix at `bits` (null: all the
// reader may read) and hands it over; returns the bytes received.
// prefix: the byte length complete at bits (ms_web_view_plan_bytes), which a
// static layout asks for as a range.
// ticket: as get()'s.
async function fetchCell(name, token, cell, bits, prefix, v, ticket) {
  v = v || view;
  const held = M._ms_web_view_held(v, cell);
  const end = layout.ranged && bits !== null ? '' + (prefix - 1) : '';
  const range = held || end ? { Range: 'bytes=' + held + '-' + end } : null;
  const answer = await get(layout.cell(name, cell, bits), token, range, ticket);
  const bytes = answer.bytes;
  timing.requests++;
  timing.requestBytes += bytes.length;
  const offset = answer.status === 206 ? held : 0;
  const st = withHeap(bytes, p => M._ms_web_view_give(v, cell, offset, p, bytes.length));
  if (st !== 0)
    throw new Error('cell ' + cell + ': ' + lastError(v));
  return bytes.length;
}

// A batch route's answer (get()'s), or null where the server has no such
// route (404, 400: an older meshserve); any other failure is thrown.
async function askBatch(path, token, ticket) {
  try {
    return await get(path, token, null, ticket);
  } catch (e) {
    if (e.cancelled || (e.status !== 404 && e.status !== 400))
      throw e;
    return null;
  }
}

// The entries of a batch route's answer (docs/BROWSER.md, "The cells
// route", "The subtrees route"): `magic`, a u32 count, then per entry
// fieldBytes of fields (a u32 key first, its u16 status at 4, its u32
// length last) and length bytes. Checks the framing against keys (the
// entries asked for, in order): [{d, at: the entry's fields in d, status,
// bytes}], or throws "WHAT: the server's answer is malformed".
function readBatch(b, magic, fieldBytes, keys, what) {
  const d = new DataView(b.buffer, b.byteOffset, b.byteLength);
  const malformed = () => new Error(what + ': the server\'s answer is malformed');
  if (b.length < 8 || String.fromCharCode(b[0], b[1], b[2], b[3]) !== magic || d.getUint32(4, true) !== keys.length)
    throw malformed();
  const entries = [];
  let at = 8;
  for (const key of keys) {
    if (at + fieldBytes > b.length)
      throw malformed();
    const status = d.getUint16(at + 4, true), length = d.getUint32(at + fieldBytes - 4, true);
    const start = at + fieldBytes;
    if (d.getUint32(at, true) !== key || length > b.length - start || (status !== 200 && length))
      throw malformed();
    entries.push({ d, at, status, bytes: b.subarray(start, start + length), malformed });
    at = start + length;
  }
  if (at !== b.length)
    throw malformed();
  return entries;
}

// Several cells' geometry in one request (the side door's cells route,
// docs/BROWSER.md "The cells route"): list holds [cell, bits, prefix] as the
// plan lists them, each asked for from the bytes held on. A cell the server
// refuses is asked for alone, whose answer says why; a server without the
// route (404, 400) is asked cell by cell from then on (cellsRoute). Returns
// the bytes received. ticket: as get()'s.
let cellsRoute = true;
async function fetchCells(name, token, list, v, ticket) {
  v = v || view;
  const items = list.map(([cell, bits, prefix]) => ({ cell, bits, prefix, from: M._ms_web_view_held(v, cell) }));
  const answer = await askBatch(layout.cells(name, items), token, ticket);
  if (!answer)
    cellsRoute = false;
  const alone = answer ? [] : items;
  let got = 0;
  if (answer) {
    const entries = readBatch(answer.bytes, 'MSB1', 16, items.map(it => it.cell), 'cells');
    entries.forEach((e, k) => {
      const it = items[k], length = e.bytes.length;
      if (e.d.getUint32(e.at + 8, true) !== it.from)
        throw e.malformed();
      if (e.status !== 200) {
        alone.push(it);
        return;
      }
      if (length && withHeap(e.bytes, p => M._ms_web_view_give(v, it.cell, it.from, p, length)) !== 0)
        throw new Error('cell ' + it.cell + ': ' + lastError(v));
      got += length;
      timing.requests++;
      timing.requestBytes += length;
    });
    timing.cellBatches++;
  }
  for (const it of alone)
    got += await fetchCell(name, token, it.cell, it.bits, it.prefix, v, ticket);
  return got;
}

// Fetches what the cell lacks of its colour stream's prefix at `bits`
// (prefix: its byte length, ms_web_view_plan_colour_bytes) and hands it
// over; returns the bytes received. ticket: as get()'s.
async function fetchColour(name, token, cell, bits, prefix, ticket) {
  const held = M._ms_web_view_colour_held(view, cell);
  const end = layout.ranged ? '' + (prefix - 1) : '';
  const range = held || end ? { Range: 'bytes=' + held + '-' + end } : null;
  const answer = await get(layout.colour(name, cell, bits), token, range, ticket);
  const bytes = answer.bytes;
  timing.requests++;
  timing.requestBytes += bytes.length;
  timing.colourBytes = (timing.colourBytes || 0) + bytes.length;
  const offset = answer.status === 206 ? held : 0;
  const st = withHeap(bytes, p => M._ms_web_view_give_colour(view, cell, offset, p, bytes.length));
  if (st !== 0)
    throw new Error('cell ' + cell + '\'s colour: ' + lastError());
  return bytes.length;
}

// Fetches subtree id of the index and hands it to view v; returns the bytes
// received (its stored bytes: a zlib stream, inflated in the module by the
// native client's reader).
async function fetchSubtree(name, token, id, v, ticket) {
  const answer = await get(layout.subtree(name, id), token, null, ticket);
  const bytes = answer.bytes;
  timing.subtrees++;
  timing.indexWireBytes += bytes.length;
  const st = withHeap(bytes, p => M._ms_web_view_give_subtree(v || view, id, p, bytes.length));
  if (st !== 0)
    throw new Error('the model\'s index: ' + lastError(v));
  return bytes.length;
}

// Several subtrees in one request (the side door's subtrees route,
// docs/BROWSER.md "The subtrees route"), each handed to view v as it is
// read; one the server refuses is asked for alone (its answer says why), and
// a server without the route (404, 400; a static site) is asked subtree by
// subtree from then on (subtreesRoute). Returns the bytes received.
let subtreesRoute = true;
async function fetchSubtrees(name, token, ids, v, ticket) {
  const answer = ids.length > 1 && layout.subtrees && subtreesRoute
    ? await askBatch(layout.subtrees(name, ids), token, ticket) : null;
  if (!answer && ids.length > 1 && layout.subtrees)
    subtreesRoute = false;
  const alone = answer ? [] : ids.slice();
  let got = 0;
  if (answer) {
    readBatch(answer.bytes, 'MSS1', 12, ids, 'subtrees').forEach((e, k) => {
      const id = ids[k], length = e.bytes.length;
      if (e.status !== 200) {
        alone.push(id);
        return;
      }
      timing.subtrees++;
      timing.indexWireBytes += length;
      got += length;
      if (withHeap(e.bytes, p => M._ms_web_view_give_subtree(v || view, id, p, length)) !== 0)
        throw new Error('the model\'s index: ' + lastError(v));
    });
    timing.subtreeBatches++;
  }
  const each = await Promise.all(alone.map(id => fetchSubtree(name, token, id, v, ticket)));
  return each.reduce((sum, n) => sum + n, got);
}

// Seconds spent, for the page's figures (window.meshstream.timing): selecting
// and decoding (plan), the rounds of fetches from their first request to
// their last answer, decoding included (fetch), of which the worker had
// nothing to do but wait for the network (wait), stitching the cut (stitch) and copying the
// mesh out of the module to the page (copy); whether the module is the
// threaded one (threaded) and the threads decoding (threads); counts:
// plans, stitches, cells answered and their bytes (requests,
// requestBytes; cellBatches: requests of several cells, fetchCells;
// subtreeBatches: of several subtrees, fetchSubtrees), cells
// and subtrees whose request a new camera cancelled (cancelled), subtrees
// of the index fetched (subtrees; byHead: whether the index came by
// subtree). indexWireBytes: the index's bytes as they travelled (head and
// subtrees, or the whole blob deflated). marks: milliseconds
// from the worker's start to its first steps (index read, first mesh
// posted); boot: boot.js's milliseconds from the navigation (the page
// asked for and answered, boot.js fetched and run) and the worker's clock
// against the page's (workerClock: a mark + workerClock is from the
// navigation); warmAnswers: of the model's first three requests, those
// the browser's cache answered (boot.js sent them first); apoLoaded:
// whether a camera wanted APO, so that its part (worker-apo.js) was read.
const timing = { plan: 0, fetch: 0, wait: 0, stitch: 0, copy: 0, threads: 1, plans: 0, stitches: 0,
                 requests: 0, requestBytes: 0, cancelled: 0, subtrees: 0, indexWireBytes: 0, byHead: false,
                 cellBatches: 0, subtreeBatches: 0, apoRequests: 0, apoBytes: 0, apoCheck: 0, warmAnswers: 0, apoLoaded: false,
                 marks: {} };

function mark(name) {
  if (!(name in timing.marks))
    timing.marks[name] = Math.round(performance.now());
}

function timed(key, fn) {
  const t = performance.now();
  try {
    return fn();
  } finally {
    timing[key] += (performance.now() - t) / 1000;
  }
}

// received: the bytes read so far (the first non-empty mesh's are kept in
// timing.firstMeshBytes: what the first look cost; firstMeshIndexBytes: of
// them, the index's).
// lastStitchMs: what the last stitch and copy took (a round shows its
// progress no more often than STITCH_SHARE times that: the stitch is the
// whole cut's, each costs more as the cut grows).
let lastStitchMs = 0;
function postMesh(final, received) {
  const t = performance.now();
  timed('stitch', () => {
    if (M._ms_web_view_stitch(view) !== 0)
      throw new Error('stitching the cut: ' + lastError());
  });
  timing.stitches++;
  timed('copy', () => copyAndPost(final));
  lastStitchMs = performance.now() - t;
  if (M._ms_web_view_triangle_count(view) && !('mesh' in timing.marks)) {
    mark('mesh');
    timing.firstMeshBytes = received;
    timing.firstMeshIndexBytes = timing.indexWireBytes;   // of them, the index's
  }
}

function copyAndPost(final) {
  const nv = M._ms_web_view_vertex_count(view), nt = M._ms_web_view_triangle_count(view);
  const positions = new Float32Array(heap(), M._ms_web_view_positions(view), 3 * nv).slice();
  const triangles = new Uint32Array(heap(), M._ms_web_view_triangles(view), 3 * nt).slice();
  const normals = new Float32Array(heap(), M._ms_web_view_normals(view), 3 * nv).slice();
  // r g b a per vertex (sRGB as scanned) on a colour model, else null
  const at = M._ms_web_view_colours(view);
  const colours = at ? new Uint8Array(heap(), at, 4 * nv).slice() : null;
  const runs = meshRuns();
  postMessage({ type: 'mesh', final, positions, normals, triangles, colours, runs,
                cells: M._ms_web_view_shown_cells(view), bits: M._ms_web_view_max_bits(view) },
              [positions.buffer, normals.buffer, triangles.buffer, runs.cells.buffer, runs.firsts.buffer,
               runs.cubes.buffer].concat(colours ? [colours.buffer] : []));
}

// The renderer's cells (web/render.js): the stitched triangles grouped by the
// cell that drew them (ms_web_view_run_*), cell k drawing triangles
// [firsts[k], firsts[k + 1]), and each cell's cube (origin, side: the frame
// of its cell-local positions and of its APO chunk).
function meshRuns() {
  const n = M._ms_web_view_run_count(view);
  const cells = n ? new Uint32Array(heap(), M._ms_web_view_run_cells(view), n).slice() : new Uint32Array(0);
  const firsts = n ? new Uint32Array(heap(), M._ms_web_view_run_firsts(view), n + 1).slice() : new Uint32Array(1);
  const cubes = new Float64Array(4 * n), p = M._malloc(32);
  try {
    for (let k = 0; k < n; ++k)
      if (M._ms_web_view_cell_cube(view, cells[k], p) === 0)
        cubes.set(new Float64Array(heap(), p, 4), 4 * k);
  } finally {
    M._free(p);
  }
  return { cells, firsts, cubes };
}

// ms_web_view_plan on the view, timed and counted.
function plan(settledPtr) {
  timing.plans++;
  return timed('plan', () => M._ms_web_view_plan(view, PLAN_MAX, settledPtr));
}

// The camera the page asked for last, not yet applied, and the wake-up of a
// settled loop waiting for one; the tickets of the cell requests in flight
// (get()'s), which a new camera cancels while they wait for their answer.
let pendingCamera = null, wake = null;
const tickets = new Set();
// The subtrees of the index asked for (in flight or held): each once.
const subtreesAsked = new Set();
// The subtrees the camera's own plan wants, asked for as soon as that plan is
// made, while the first look decodes (run()): {ids, promise, ticket}; the
// round that would ask for them waits for this request instead.
let earlyFetch = null;

function nextCamera() {
  return new Promise(resolve => { wake = resolve; });
}

// Of the paths boot.js asked for first (its prefetch message's firstPaths),
// those whose last answer here came from the browser's cache: no byte on the
// wire (a resource timing's transferSize), a body all the same.
let firstPaths = [];
function warmAnswers() {
  return firstPaths.filter(path => {
    const e = performance.getEntriesByName(new URL(path, ROOT).href).pop();
    return !!e && e.transferSize === 0 && e.decodedBodySize > 0;
  }).length;
}

// The catalogue's entry and the index of the model a message names, asked for
// at once: {name, token, layout, listing, index} (promises).
let prefetched = null;
function prefetch(msg) {
  layout = LAYOUTS[msg.layout] || LAYOUTS.door;
  mark('prefetch');
  if (Array.isArray(msg.firstPaths))
    firstPaths = msg.firstPaths;
  if (msg.boot && typeof msg.boot.timeOrigin === 'number') {
    // boot.js's times, and this worker's clock against the page's
    timing.boot = Object.assign({}, msg.boot, {
      workerClock: Math.round(performance.timeOrigin - msg.boot.timeOrigin) });
    delete timing.boot.timeOrigin;
  }
  // the catalogue's entries whose name (or title, description) holds NAME
  // (a page of at most 1000)
  const listing = get(layout.catalogue(msg.name), msg.token).then(
    answer => JSON.parse(new TextDecoder().decode(answer.bytes)),
    e => { throw new Error('cannot read the catalogue: ' + e.message); });
  listing.catch(() => {});        // told by run(), if it runs
  // the index's failure is told after the catalogue's verdict (an unknown
  // model is named as such, not as the index's 404)
  const index = get(layout.head(msg.name), msg.token).catch(e => e);
  // the root cell, all of it the reader may read (no ?bits: never refused):
  // the first look draws from it without a round trip of its own, the home
  // camera is framed by it, and every view deeper than the root needs it
  // whole (a split cell stays at its finest bits)
  const root = get(layout.cell(msg.name, 0, null), msg.token).catch(e => e);
  return { name: msg.name, token: msg.token, layout: msg.layout, listing, index, root };
}

async function run(msg) {
  mark('start');
  const { name, token } = msg;
  const started = performance.now();
  // The module compiles while the catalogue's entry and the index arrive: the
  // three at once, not one round trip after another (first pixels), and
  // from the page's first script on (boot.js's prefetch).
  const { listing, index, root } = prefetched && prefetched.name === name && prefetched.token === token &&
                             prefetched.layout === msg.layout ? prefetched : prefetch(msg);
  const module = loadModule();
  layout = LAYOUTS[msg.layout] || LAYOUTS.door;
  const [catalogue, headAnswer] = await Promise.all([
    listing.then(c => { mark('catalogue'); return c; }),
    index.then(a => { mark('index fetched'); return a; }),
    module.then(m => { M = m; mark('module'); })]);
  const entry = catalogue.models.find(m => m.name === name);
  if (!entry)
    throw new Error('no model named "' + name + '" on this server');
  // the head; without one (404: a static site exported before heads) the
  // whole index, one round trip later
  let indexAnswer = headAnswer, byHead = true;
  if (indexAnswer instanceof Error && indexAnswer.status === 404) {
    byHead = false;
    indexAnswer = await get(layout.index(name), token).catch(e => e);
  }
  if (indexAnswer instanceof Error)
    throw indexAnswer;
  const blob = indexAnswer.bytes;
  // the index as it travelled (the whole blob deflated by meshserve for a
  // browser: the page's bytes count it inflated; a head is sent as stored)
  timing.indexWireBytes = indexAnswer.headers.get('Content-Encoding') === 'deflate' &&
                          Number(indexAnswer.headers.get('Content-Length')) > 0
    ? Number(indexAnswer.headers.get('Content-Length')) : blob.length;
  timing.byHead = byHead;
  mark('index');
  view = openIndex(blob, name, byHead);
  timing.threaded = threaded;     // the threaded module (a cross-origin isolated page)
  opened = { name, token, blob, byHead };
  applySections();
  const bp = M._malloc(32);
  M._ms_web_view_box(view, bp);
  const box = Array.from(new Float64Array(heap(), bp, 4));
  M._free(bp);
  let bytes = blob.length, rounds = 0, bounds = null;
  const rootAnswer = await root;
  // the root's bytes from `from` to `to` (all of them: counted once)
  const giveRoot = (from = 0, to = Infinity) => {
    if (rootAnswer instanceof Error)
      return;
    const got = rootAnswer.bytes.subarray(from, to);
    if (from === 0) {
      timing.requests++;
      timing.requestBytes += rootAnswer.bytes.length;
      bytes += rootAnswer.bytes.length;
    }
    if (got.length && withHeap(got, p => M._ms_web_view_give(view, 0, from, p, got.length)) !== 0)
      throw new Error('cell 0: ' + lastError());
  };
  let homeCut = 0;
  if (!msg.camera) {
    // the root at HOME_BITS tells where the model lies in its box: the home
    // camera (all of it took 0.5 s to decode), drawn at once; the rest after
    homeCut = rootAnswer instanceof Error ? 0 : M._ms_web_view_prefix(view, 0, HOME_BITS);
    giveRoot(0, homeCut);
    if (rootAnswer instanceof Error)
      bytes += await fetchCell(name, token, 0, null, 0);
    const p = M._malloc(48);
    if (M._ms_web_view_bounds(view, p) === 0)
      bounds = Array.from(new Float64Array(heap(), p, 6));
    M._free(p);
  }
  // the unit the model's metadata declares (docs/ARCHIVE.md, "Metadata"), for
  // the measuring line; null: "model units"
  postMessage({ type: 'box', box, bounds, triangles: entry.triangles,
                unit: typeof entry.unit === 'string' && entry.unit ? entry.unit : null });
  if (homeCut) {
    postMesh(false, bytes);
    giveRoot(homeCut);
  }
  // A reader without a token reads a preview model to public_max_bits only.
  M._ms_web_view_culled(view, msg.culled);
  // received streams kept at most (view.js: #mem=, or from the device's memory)
  if (msg.memory > 0)
    M._ms_web_view_budget(view, Math.min(msg.memory, 0xFFFFFFFF) >>> 0);
  timing.memoryBudget = msg.memory > 0 ? msg.memory : 0;
  // A static tree holds only what its catalogue lists as public (meshexport
  // --full lists every bit): no server there widens it for a token.
  const preview = (!token || layout.ranged) && entry.public_max_bits < entry.bits;
  if (preview)
    M._ms_web_view_permit(view, entry.public_max_bits + 1);
  opened.permit = preview ? entry.public_max_bits + 1 : 0;
  const settledPtr = M._malloc(4);
  if (msg.camera) {
    // the subtrees the camera's own plan wants first travel with the first
    // look (earlySubtrees); the root's bytes come once its tolerance is
    // chosen (each plan tried would decode the root as far as it wants)
    setCamera(msg.camera);
    M._ms_web_view_plan_ahead(view, 1);
    if (plan(settledPtr) !== 0)
      throw new Error('selecting the cut: ' + lastError());
    const ids = [];
    for (let k = 0, n = M._ms_web_view_plan_subtree_count(view); k < n; ++k)
      ids.push(M._ms_web_view_plan_subtree(view, k));
    if (ids.length) {
      const ticket = { cancel: new AbortController(), started: false };
      tickets.add(ticket);
      ids.forEach(id => subtreesAsked.add(id));
      const promise = fetchSubtrees(name, token, ids, view, ticket).finally(() => tickets.delete(ticket));
      promise.catch(() => {});      // (its error is the round's, which awaits it)
      earlyFetch = { ids, promise, ticket };
      mark('early subtrees');
    }
    pendingCamera = msg.camera;
  }
  while (!pendingCamera)
    await nextCamera();
  let seq = 0;                    // the page's number of the camera applied
  // A first look: with nothing drawn yet (a camera from the URL), the first
  // round selects at the finest of a few coarser tolerances whose bytes stay
  // within FIRST_LOOK_BYTES: the coarse levels, drawn within a round trip.
  // The rounds after it refine from there, and the streams being
  // progressive, its bytes are the prefixes they extend, not extra bytes.
  // By subtree, the first look is a cut of the cells known (its plan wants
  // no subtree: drawn without waiting for one; the root came with the head).
  const firstLookCamera = c => {
    for (const times of FIRST_LOOK) {
      // (the first look draws no APO: its chunks come once a view settles)
      const coarse = Object.assign({}, c, { tolerance: c.tolerance * times, apo: false });
      setCamera(coarse);
      if (plan(settledPtr) !== 0)
        throw new Error('selecting the cut: ' + lastError());
      if (planNeed(M._ms_web_view_plan_count(view)) <= FIRST_LOOK_BYTES &&
          M._ms_web_view_plan_subtree_count(view) === 0)
        return;
    }
  };
  let current = null, looking = false, firstLook = !bounds, rootGiven = false;
  for (;;) {
    if (pendingCamera) {
      current = pendingCamera;
      seq = current.seq;
      pendingCamera = null;
      looking = firstLook;
      firstLook = false;
      // the first look's plans see the next step only (their bytes are
      // weighed against FIRST_LOOK_BYTES); the camera's own look ahead
      M._ms_web_view_plan_ahead(view, looking ? 0 : 1);
      if (looking)
        firstLookCamera(current);
      else
        setCamera(current);
      if (msg.camera && !rootGiven) {
        rootGiven = true;
        giveRoot();
      }
    } else if (looking) {
      looking = false;            // the first look is in: the camera's own tolerance
      M._ms_web_view_plan_ahead(view, 1);
      setCamera(current);
    }
    if (plan(settledPtr) !== 0)
      throw new Error('selecting the cut: ' + lastError());
    const count = M._ms_web_view_plan_count(view);
    if (U32()[settledPtr >> 2] && looking) {
      postMesh(false, bytes);
      startHelpers();
      continue;
    }
    if (U32()[settledPtr >> 2]) {
      postMesh(true, bytes);
      if (apoWanted(current))       // the APO chunks the view wants (web/worker-apo.js)
        bytes += await apoRound(name, token);
      timing.warmAnswers = warmAnswers();
      timing.forgottenCells = M._ms_web_view_forgotten_cells(view);
      timing.forgottenBytes = M._ms_web_view_forgotten_bytes(view);
      postMessage({ type: 'complete', seq, bytes, rounds, preview, timing,
                    seconds: (performance.now() - started) / 1000 });
      while (!pendingCamera)
        await nextCamera();
      continue;
    }
    // what this plan decoded, at once: the root the home camera was framed
    // with, then each round's cells (before, a round's picture waited for
    // the next round's fetches)
    if (changed(count) || (rounds === 0 && bounds))
      postMesh(false, bytes);
    startHelpers();                 // (the home camera's: after the root's picture)
    const wanted = [];
    for (let k = 0; k < count; ++k)
      wanted.push([M._ms_web_view_plan_cell(view, k), M._ms_web_view_plan_bits(view, k),
                   M._ms_web_view_plan_bytes(view, k)]);
    // a colour model's colour prefixes, after the cells' geometry
    const colours = [], colourQueued = new Map();
    const listColours = () => {
      for (let k = 0, n = M._ms_web_view_plan_colour_count(view); k < n; ++k) {
        const cell = M._ms_web_view_plan_colour_cell(view, k), bits = M._ms_web_view_plan_colour_bits(view, k);
        if (!colourQueued.has(cell) || colourQueued.get(cell) < bits) {
          colourQueued.set(cell, bits);
          colours.push([cell, bits, M._ms_web_view_plan_colour_bytes(view, k)]);
        }
      }
    };
    listColours();
    // the subtrees of the index the plan lacks: asked for before any cell
    // (each unblocks the splits below it), each once
    const subtrees = [];
    let early = earlyFetch;       // the first look's request of subtrees, still this round's to wait for
    earlyFetch = null;
    const listSubtrees = () => {
      const ids = [];
      for (let k = 0, n = M._ms_web_view_plan_subtree_count(view); k < n; ++k)
        ids.push(M._ms_web_view_plan_subtree(view, k));
      for (const id of ids) {
        if (!subtreesAsked.has(id)) {
          subtreesAsked.add(id);
          subtrees.push(id);
        }
      }
    };
    listSubtrees();
    if (!wanted.length && !subtrees.length && !colours.length && !early)   // (never: a guard against a busy loop)
      throw new Error('selecting the cut: the plan wants subtrees it has asked for already');
    // the bytes this round still wants: the page's progress bar
    let need = planNeed(count);
    postMessage({ type: 'progress', bytes, need, rounds, wanted: count });
    let next = 0, given = 0, shownAt = performance.now(), fresh = 0;
    const queued = new Map(wanted.map(([cell, bits]) => [cell, bits]));
    // A long round decodes what has come every DECODE_EVERY_BYTES and
    // shows it every SHOW_EVERY_MS, and at once when a subtree of the index
    // came (its cells are then known to the plans): decoding the cells
    // given so far overlaps the fetches still on their way (the browser's
    // network goes on while the worker decodes), and the picture fills in
    // cell by cell instead of waiting for the round.
    // What that plan lists beyond the round (the children of the cells
    // just decoded, the subtrees below them) joins the round's queues while
    // the camera stays, so the next level's fetches start without waiting
    // for the round's last cell.
    const replan = force => {
      const showDue = performance.now() - shownAt >= Math.max(SHOW_EVERY_MS, STITCH_SHARE * lastStitchMs);
      if (!force && !(given < wanted.length && (showDue || fresh >= DECODE_EVERY_BYTES)))
        return;
      fresh = 0;
      if (plan(settledPtr) !== 0)
        throw new Error('selecting the cut: ' + lastError());
      const listed = M._ms_web_view_plan_count(view);
      if (showDue && changed(listed)) { // stitching is the whole cut's: not every decode
        postMesh(false, bytes);
        shownAt = performance.now();
      }
      if (pendingCamera)
        return;
      listSubtrees();
      listColours();
      for (let k = 0; k < listed; ++k) {
        const cell = M._ms_web_view_plan_cell(view, k), bits = M._ms_web_view_plan_bits(view, k);
        if (!queued.has(cell) || queued.get(cell) < bits) {
          queued.set(cell, bits);
          const prefix = M._ms_web_view_plan_bytes(view, k);
          need += Math.max(prefix - M._ms_web_view_held(view, cell), 0);
          wanted.push([cell, bits, prefix]);
        }
      }
    };
    // One request, a subtree or a cell. A new camera ends the round: nothing more of the old plan is asked
    // for, what still waits for its answer's head is cancelled (tickets,
    // the message handler below; timing.cancelled counts them), what is
    // arriving lands; the next plan asks again what the new view still
    // needs.
    const job = async ([kind, ...what]) => {
      const ticket = { cancel: new AbortController(), started: false };
      tickets.add(ticket);
      let got;     // not `bytes += await`: jobs interleave
      try {
        got = kind === 'early' ? await what[0].promise
            : kind === 'subtrees' ? await fetchSubtrees(name, token, what[0], view, ticket)
            : kind === 'colour' ? await fetchColour(name, token, what[0], what[1], what[2], ticket)
            : kind === 'cells' ? await fetchCells(name, token, what[0], view, ticket)
                                 : await fetchCell(name, token, what[0], what[1], what[2], view, ticket);
      } catch (e) {
        if (!e.cancelled)
          throw e;
        const ids = kind === 'early' ? what[0].ids : kind === 'subtrees' ? what[0] : [];
        timing.cancelled += kind === 'cells' ? what[0].length : kind === 'colour' || kind === 'cell' ? 1 : ids.length;
        ids.forEach(id => subtreesAsked.delete(id));   // cells (or subtrees) given up
        return;
      } finally {
        tickets.delete(ticket);
      }
      bytes += got;
      if (kind === 'cell' || kind === 'cells') {
        need = Math.max(need - got, 0);
        given += kind === 'cells' ? what[0].length : 1;
        fresh += got;
      }
      postMessage({ type: 'progress', bytes, need, rounds, wanted: count });
      replan(kind === 'subtrees' || kind === 'early');
    };
    // IN_FLIGHT requests at a time, subtrees first; a request that ends
    // starts the next, so what a plan adds mid-round goes out at once.
    const fetchStart = performance.now(), busy = timing.plan + timing.stitch + timing.copy;
    await new Promise((resolve, reject) => {
      let active = 0, failure = null;
      const pump = () => {
        while (!failure && !pendingCamera && active < IN_FLIGHT &&
               (early || subtrees.length || next < wanted.length || colours.length)) {
          active++;
          if (early) {
            job(['early', early]).then(() => { active--; pump(); },
                                       e => { active--; failure = failure || e; pump(); });
            early = null;
            continue;
          }
          // the side door's cells route takes several at once, each from
          // its bytes held on (a cell the plan wants whole, bits null, alone)
          let batch = 0;
          while (layout.cells && cellsRoute && batch < BATCH_CELLS && next + batch < wanted.length &&
                 wanted[next + batch][1] !== null)
            ++batch;
          // the subtrees queued, in one request where the route takes several
          const some = layout.subtrees && subtreesRoute ? BATCH_SUBTREES : 1;
          job(subtrees.length ? ['subtrees', subtrees.splice(0, some)]
              : batch > 1 ? ['cells', wanted.slice(next, next += batch)]
              : next < wanted.length ? ['cell', ...wanted[next++]] : ['colour', ...colours.shift()]).then(
            () => { active--; pump(); },
            e => { active--; failure = failure || e; pump(); });
        }
        if (active === 0)
          failure ? reject(failure) : resolve();
      };
      pump();
    });
    if (early)                    // (a new camera came first: the next round waits for it)
      earlyFetch = early;
    const roundSeconds = (performance.now() - fetchStart) / 1000;
    timing.fetch += roundSeconds;
    // the round's time the worker did not decode, stitch or copy: waiting on
    // the network (and on the browser's own work for the fetches)
    timing.wait += Math.max(roundSeconds - (timing.plan + timing.stitch + timing.copy - busy), 0);
    rounds++;
  }
}

// The bytes the plan's cells lack of the prefixes it lists.
function planNeed(count) {
  let need = 0;
  for (let k = 0; k < count; ++k)
    need += Math.max(M._ms_web_view_plan_bytes(view, k) -
                     M._ms_web_view_held(view, M._ms_web_view_plan_cell(view, k)), 0);
  return need;
}

// Whether the cut differs from the one last posted (its shown cells, their
// finest bits and the bytes held behind them): a plan that decoded nothing
// new posts nothing. `count`: the plan's length, which changes with the cut.
let lastShown = null;
function changed(count) {
  const now = [M._ms_web_view_shown_cells(view), M._ms_web_view_max_bits(view),
               Number(M._ms_web_view_bytes_held(view)), count, M._ms_web_view_plan_colour_count(view)].join(',');
  const differs = now !== lastShown;
  lastShown = now;
  return differs;
}

// The section planes asked for (applied once the view exists), and what
// the model was opened with (a probe opens it again).
let sections = [], opened = null;

function applySections(v) {
  v = v || view;
  if (!v)
    return;
  const p = M._malloc(Math.max(sections.length, 1) * 32);
  new Float64Array(heap(), p, 4 * sections.length).set(sections.flat());
  const st = M._ms_web_view_sections(v, p, sections.length);
  M._free(p);
  if (st !== 0)
    fail('section planes: ' + lastError(v));
}

onmessage = e => {
  if (e.data.type === 'module') {
    mark('module from the page');
    fromPage(e.data);
    return;
  }
  if (e.data.type === 'prefetch') {
    prefetched = prefetch(e.data);
    loadModule();
    return;
  }
  if (e.data.type === 'sections') {
    sections = e.data.planes;
    applySections();
    return;
  }
  if (e.data.type === 'cast') {
    if (typeof cast !== 'function')
      importScripts('probe.js');    // the measuring tools: cast()
    cast(e.data);
    return;
  }
  if (e.data.type === 'refine') {
    if (typeof refine !== 'function')
      importScripts('probe.js');    // the measuring probe: refine()
    refine(e.data).catch(err => fail('refining a measuring point: ' + (err.message || String(err))));
    return;
  }
  if (e.data.type === 'start') {
    run(e.data).catch(err => fail(err.message || String(err)));
  } else if (e.data.type === 'camera') {
    pendingCamera = e.data.camera;
    for (const ticket of tickets)
      if (!ticket.started)
        ticket.cancel.abort();
    if (wake) {
      wake();
      wake = null;
    }
  }
};
