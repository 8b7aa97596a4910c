// The worker's APO part (docs/BROWSER.md, "APO"), loaded by worker.js the
// first time a camera wants APO (apoWanted) and run in its global scope (M,
// view, layout, get, withHeap, timing, pendingCamera, lastError, apoWanted
// are worker.js's). Once a camera's cut is
// settled and the page's shading draws APO normals (meshview's rule: every
// mode but --shading geometry), the client core's rule picks the chunks'
// levels (ms_web_apo_plan: visible shown cells, not about to split, by
// footprint, at most APO_LEVELS, under a preview no finer than the preview:
// the server's own function), each is fetched through the side door's
// permission-checked route (GET models/NAME/cells/ID/apo?levels=L; a static
// export's whole file by byte range), inflated by the browser
// (DecompressionStream: the stored chunk is one zlib stream with a sync flush
// after each level, so a prefix of whole levels inflates alone), checked by
// the native loader (ms_web_apo_give: ms_apo_view_init) and posted to the
// page: {type: 'apo', cell, levels, words (Uint32Array, transferred),
// rootWords (1: a leaf root, 2: internal)}.
'use strict';

const APO_LEVELS = 16;        // meshview's --apo-levels default: the footprint decides
const DETAIL_TOLERANCE = 1;   // px: meshview's detail tolerance with APO (the core's tolerance_px)
const APO_IN_FLIGHT = 16;
let apoState = null, apoView = null;
const apoHeld = new Map();    // cell: the stored chunk's bytes held (a prefix)

const apoPath = (name, cell, levels) => 'models/' + encodeURIComponent(name) + '/cells/' + cell + '/apo' +
  (layout.ranged ? '' : '?levels=' + levels);

// The words of the first `count` of a zlib stream's prefix (sync-flushed at
// a level's end): read until they are all out, then the rest cancelled (a
// prefix is a stream without its end, which closing would call an error).
async function apoInflate(bytes, count) {
  const stream = new DecompressionStream('deflate');
  const writer = stream.writable.getWriter(), reader = stream.readable.getReader();
  writer.write(bytes).catch(() => {});
  const out = new Uint8Array(4 * count);
  let at = 0;
  try {
    while (at < out.length) {
      const { value, done } = await reader.read();
      if (done)
        break;
      out.set(value.subarray(0, Math.min(value.length, out.length - at)), at);
      at += value.length;
    }
  } catch (e) {
    throw new Error('an APO chunk does not inflate: ' + e.message);
  } finally {
    reader.cancel().catch(() => {});
    writer.abort().catch(() => {});
  }
  if (at < out.length)
    throw new Error('an APO chunk inflates to ' + at + ' bytes, not ' + out.length);
  return new Uint32Array(out.buffer);
}

// One cell's levels: fetched (only what is not held), inflated, checked,
// posted. Returns the bytes received.
async function apoCell(name, token, cell, levels, end) {
  const held = apoHeld.get(cell) || new Uint8Array(0);
  const range = held.length || layout.ranged
    ? { Range: 'bytes=' + held.length + '-' + (layout.ranged ? '' + (end - 1) : '') } : null;
  const answer = await get(apoPath(name, cell, levels), token, range);
  timing.apoRequests++;
  timing.apoBytes += answer.bytes.length;
  let all = answer.bytes;
  if (answer.status === 206 && held.length) {
    all = new Uint8Array(held.length + answer.bytes.length);
    all.set(held);
    all.set(answer.bytes, held.length);
  }
  if (all.length !== end)
    throw new Error('cell ' + cell + ': an APO prefix of ' + all.length + ' bytes, not ' + end);
  apoHeld.set(cell, all);
  let count = 0;
  for (let l = 0; l < levels; ++l)
    count += M._ms_web_apo_level_texels(apoState, cell, l);
  const words = await apoInflate(all, count);
  const t = performance.now();
  const st = withHeap(new Uint8Array(words.buffer), p => M._ms_web_apo_give(apoState, cell, levels, p, count));
  timing.apoCheck += (performance.now() - t) / 1000;
  if (st !== 0)
    throw new Error('cell ' + cell + ': ' + lastError());
  postMessage({ type: 'apo', cell, levels, words, rootWords: M._ms_web_apo_level_texels(apoState, cell, 0) },
              [words.buffer]);
  return answer.bytes.length;
}

// The APO state of the worker's view (made afresh for a new view).
function apoOf() {
  if (apoView !== view) {
    M._ms_web_apo_free(apoState);
    apoState = M._ms_web_apo_new(view);
    apoView = view;
    apoHeld.clear();
    if (!apoState)
      throw new Error('out of memory in the WebAssembly module');
  }
  return apoState;
}

// After each camera of the view: the geometry meshview's core selects with
// APO drawn or not (ms_web_apo_geometry: with APO, the cells without a chunk
// refine to the detail tolerance).
function apoCamera(c) {
  M._ms_web_apo_geometry(apoOf(), apoWanted(c) ? 1 : 0, DETAIL_TOLERANCE);
}

// The chunks the settled view wants, all of them unless a new camera comes.
async function apoRound(name, token) {
  apoOf();
  const n = M._ms_web_apo_plan(apoState, APO_LEVELS, DETAIL_TOLERANCE), wanted = [];
  for (let k = 0; k < n; ++k)
    wanted.push([M._ms_web_apo_plan_cell(apoState, k), M._ms_web_apo_plan_levels(apoState, k),
                 M._ms_web_apo_plan_bytes(apoState, k)]);
  let next = 0, received = 0;
  const lane = async () => {
    while (next < wanted.length && !pendingCamera) {
      const [cell, levels, end] = wanted[next++];
      received += await apoCell(name, token, cell, levels, end);
    }
  };
  await Promise.all(Array.from({ length: Math.min(APO_IN_FLIGHT, wanted.length) }, lane));
  return received;
}
