// Measuring in the page (docs/BROWSER.md, "Measuring"), meshview's
// (client/view/ms_viewer_measure.h): T (or the measure button) turns
// measuring on; each click (press and release without a drag) then adds the
// surface point under the cursor to a chain, Backspace removes the last
// point, Delete clears the chain. A point is where the ray from the eye
// through the pixel first meets the decoded cut: the worker casts it in
// doubles on the stitched mesh (ms_web_view_cast), skipping what the section
// planes cut away, and tells the bits of the point's cell; the point's
// precision is the grid step at those bits (box side / 2^bits). A segment's
// precision is the coarser of its two points' steps, the chain's their sum;
// "full" when every point's cell is at the model's bits. Each point keeps
// its ray, and every new mesh casts it again from its anchor (the hit
// nearest it along its ray), so as the cut refines under it the point
// follows the finer surface and its precision rises.
// A point is {anchor, direction, hit: null or {point, t, bits, step}}.
'use strict';

const MsMeasure = (() => {
  const MAX = 16;

  // The ray from the eye through framebuffer point (x, y) (top-left origin,
  // continuous) of a camera {position, target, up, fovy} on width x height.
  function pixelRay(c, x, y, width, height) {
    const f0 = [0, 1, 2].map(a => c.target[a] - c.position[a]);
    const fl = Math.hypot(...f0), f = f0.map(v => v / fl);
    const r0 = [f[1] * c.up[2] - f[2] * c.up[1], f[2] * c.up[0] - f[0] * c.up[2], f[0] * c.up[1] - f[1] * c.up[0]];
    const rl = Math.hypot(...r0), r = r0.map(v => v / rl);
    const u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]];
    const th = Math.tan(c.fovy * Math.PI / 360), aspect = width / height;
    const sx = (2 * x / width - 1) * th * aspect, sy = (1 - 2 * y / height) * th;
    const d = [0, 1, 2].map(a => f[a] + sx * r[a] + sy * u[a]);
    const dl = Math.hypot(...d);
    return { origin: c.position.slice(), direction: d.map(v => v / dl) };
  }

  // The chain's figures, or null with fewer than two points or one not found.
  function result(points, modelBits) {
    if (points.length < 2 || points.some(p => !p.hit))
      return null;
    let length = 0, precision = 0, last = 0;
    for (let i = 1; i < points.length; ++i) {
      const a = points[i - 1].hit, b = points[i].hit;
      last = Math.hypot(b.point[0] - a.point[0], b.point[1] - a.point[1], b.point[2] - a.point[2]);
      length += last;
      precision += Math.max(a.step, b.step);
    }
    const bitsMin = Math.min(...points.map(p => p.hit.bits));
    return { points: points.length, length, precision, lastLength: last, bitsMin,
             full: points.every(p => p.hit.bits >= modelBits) };
  }

  // meshview's HUD line: "measure 3 points: 1.41 +- 0.032 model units (6 bits)",
  // in unit when the model's metadata declares one ("... 1.41 +- 0.032 mm ...").
  function describe(points, modelBits, unit) {
    const r = result(points, modelBits);
    if (!r)
      return 'measure ' + points.length + ' point' + (points.length === 1 ? '' : 's') +
             (points.length >= 2 ? ': not on the surface drawn' : '');
    let decimals = r.precision > 0 ? 1 - Math.floor(Math.log10(r.precision)) : 6;
    decimals = Math.max(0, Math.min(12, decimals));
    return 'measure ' + r.points + ' points: ' + r.length.toFixed(decimals) + ' +- ' +
           r.precision.toFixed(decimals) + ' ' + (unit || 'model units') + ' (' + r.bitsMin + ' bits' + (r.full ? ', full' : '') + ')';
  }

  // Where a world point falls on the canvas (CSS pixels), or null behind the eye.
  function project(c, p, width, height) {
    const f0 = [0, 1, 2].map(a => c.target[a] - c.position[a]);
    const fl = Math.hypot(...f0), f = f0.map(v => v / fl);
    const r0 = [f[1] * c.up[2] - f[2] * c.up[1], f[2] * c.up[0] - f[0] * c.up[2], f[0] * c.up[1] - f[1] * c.up[0]];
    const rl = Math.hypot(...r0), r = r0.map(v => v / rl);
    const u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]];
    const q = [0, 1, 2].map(a => p[a] - c.position[a]);
    const z = q[0] * f[0] + q[1] * f[1] + q[2] * f[2];
    if (!(z > 0))
      return null;
    const th = Math.tan(c.fovy * Math.PI / 360), aspect = width / height;
    const x = (q[0] * r[0] + q[1] * r[1] + q[2] * r[2]) / (z * th * aspect);
    const y = (q[0] * u[0] + q[1] * u[1] + q[2] * u[2]) / (z * th);
    return [(x + 1) * width / 2, (1 - y) * height / 2];
  }

  // The points (small yellow squares) and the dotted segments between them,
  // on a 2D canvas laid over the WebGL one (no pointer events).
  let overlay = null;
  function draw(points, camera) {
    if (!overlay) {
      overlay = document.createElement('canvas');
      overlay.id = 'measure-overlay';
      document.body.appendChild(overlay);
    }
    const w = overlay.clientWidth, h = overlay.clientHeight;
    if (overlay.width !== w || overlay.height !== h) {
      overlay.width = w;
      overlay.height = h;
    }
    const g = overlay.getContext('2d');
    g.clearRect(0, 0, w, h);
    if (!camera)
      return;
    const at = points.map(p => p.hit ? project(camera, p.hit.point, w, h) : null);
    g.strokeStyle = g.fillStyle = '#ffd21a';
    g.lineWidth = 1.5;
    g.setLineDash([4, 4]);
    g.beginPath();
    for (let i = 1; i < at.length; ++i)
      if (at[i - 1] && at[i]) {
        g.moveTo(at[i - 1][0], at[i - 1][1]);
        g.lineTo(at[i][0], at[i][1]);
      }
    g.stroke();
    for (const q of at)
      if (q)
        g.fillRect(q[0] - 3, q[1] - 3, 6, 6);
  }

  return { MAX, pixelRay, result, describe, draw };
})();
