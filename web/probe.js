// The measuring tools' part of the viewer's decoding worker (web/worker.js,
// which loads this file with importScripts at its first 'cast' or 'refine'
// message: none of it is on the way to the first pixels): casts on the last
// mesh and the probe. It runs in the worker's global scope: the module (M),
// the view (view), its helpers (openIndex, fetchSubtree, fetchCell,
// applySections) and what the model was opened with (opened) are
// worker.js's.
'use strict';

// The cast of a ray on view v's last stitch: {point, t, bits, step,
// modelBits} or null. p: 13 doubles of the heap.
function castOne(v, r, p) {
  const d = new Float64Array(heap(), p, 13);
  d.set([...r.origin, ...r.direction]);
  if (!M._ms_web_view_cast(v, p, p + 24, r.tMin, r.tNear, p + 48))
    return null;
  const o = Array.from(new Float64Array(heap(), p + 48, 7));
  return { point: o.slice(0, 3), t: o[3], bits: o[4], step: o[5], modelBits: o[6] };
}

function cast(msg) {
  const hits = [];
  const p = view ? M._malloc(13 * 8) : 0;
  for (const r of msg.rays)
    hits.push(view ? castOne(view, r, p) : null);
  if (p)
    M._free(p);
  postMessage(Object.assign({}, msg, { type: 'cast', hits }));
}

// The probe (meshview's ms_viewer_probe.h): the cells under a measuring
// point refined to full precision by a view of its own, which sees only the
// point (from a thousandth of the box side in front of it along its ray, a
// hundredth of a degree on 1000 x 1000 pixels: the cells there want more
// bits than the model has; nothing outside wanted, culled 64 bits less),
// fetched to settled (the browser's cache holds what the view fetched);
// then the ray cast on its mesh. Answers {type: 'cast', refine: true, seq,
// index, hit}.
async function refine(msg) {
  if (!opened)
    return;
  const box = new Float64Array(4), bp = M._malloc(32);
  M._ms_web_view_box(view, bp);
  box.set(new Float64Array(heap(), bp, 4));
  M._free(bp);
  for (const [index, r] of msg.points.entries()) {
    const probe = openIndex(opened.blob, opened.name, opened.byHead);
    let hit = null;
    try {
      M._ms_web_view_culled(probe, 64);
      if (opened.permit)
        M._ms_web_view_permit(probe, opened.permit);
      applySections(probe);
      const len = Math.hypot(...r.direction), dir = r.direction.map(x => x / len);
      const back = box[3] / 1000, position = r.point.map((x, a) => x - back * dir[a]);
      const side = Math.abs(dir[1]) < 0.9 ? [0, 1, 0] : [1, 0, 0];
      const p = M._malloc(13 * 8);
      try {
        new Float64Array(heap(), p, 9).set([...position, ...r.point, ...side]);
        if (M._ms_web_view_camera(probe, p, p + 24, p + 48, 0.01, 1000, 1000, 0, 0, 1) !== 0)
          throw new Error(lastError(probe));
        const settled = p + 72;
        for (let round = 0; round < 64; ++round) {
          if (M._ms_web_view_plan(probe, PLAN_MAX, settled) !== 0)
            throw new Error(lastError(probe));
          if (U32()[settled >> 2])
            break;
          for (let k = 0, n = M._ms_web_view_plan_subtree_count(probe); k < n; ++k)
            await fetchSubtree(opened.name, opened.token, M._ms_web_view_plan_subtree(probe, k), probe);
          const n = M._ms_web_view_plan_count(probe);
          for (let k = 0; k < n; ++k)
            await fetchCell(opened.name, opened.token, M._ms_web_view_plan_cell(probe, k),
                            M._ms_web_view_plan_bits(probe, k), M._ms_web_view_plan_bytes(probe, k), probe);
        }
        if (M._ms_web_view_stitch(probe) !== 0)
          throw new Error(lastError(probe));
        hit = castOne(probe, { origin: position, direction: dir, tMin: 0, tNear: back }, p);
      } finally {
        M._free(p);
      }
    } catch (e) {
      hit = null;             // the point stays as the view has it
    } finally {
      M._ms_web_view_free(probe);
    }
    postMessage({ type: 'cast', refine: true, seq: msg.seq, index, hit });
  }
}
