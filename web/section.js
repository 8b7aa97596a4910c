// The page's section planes (docs/BROWSER.md, "Sections"), meshview's
// (client/view/ms_viewer_section.h): one to three planes, each a point and a
// normal in model coordinates; the side the normal points to is cut away (p
// kept where normal . (p - point) <= 0). The fragment shader discards what a
// plane cuts away (WebGL 2 has no gl_ClipDistance) and draws the back faces
// seen through the cut flat in the section colour, sRGB 214 64 48, as
// meshview does: the cut reads as a filled outline. The worker gets the
// planes too: its selection asks for the cells wholly cut away as for those
// outside the view (coarser, never split for the view), and measuring skips
// what they cut away.
// Keys as meshview's: Y adds a plane through the orbit centre across the axis
// nearest the view direction, cutting away the half towards the eye; J turns
// the last one over; 9 / 0 move it back / forward along its normal by 1/50 of
// the model's box (forward: less cut away); I removes it.
'use strict';

const MsSection = (() => {
  const MAX = 3;
  const COLOUR = [214 / 255, 64 / 255, 48 / 255];

  // a b c d per plane: the side a x + b y + c z + d > 0 cut away
  function planes(list) {
    return list.map(s => [...s.normal, -(s.normal[0] * s.point[0] + s.normal[1] * s.point[1] +
                                         s.normal[2] * s.point[2])]);
  }

  // A key (KeyboardEvent.key) on the list for a camera and the model's box
  // side: the new list, or null when the key is none of them.
  function key(list, k, camera, boxSide) {
    const out = list.map(s => ({ point: s.point.slice(), normal: s.normal.slice() }));
    const last = out[out.length - 1];
    switch (k.toLowerCase()) {
    case 'y': {
      if (out.length === MAX)
        return out;
      const f = [0, 1, 2].map(a => camera.target[a] - camera.position[a]);
      let axis = 0;
      for (let a = 1; a < 3; ++a)
        if (Math.abs(f[a]) > Math.abs(f[axis]))
          axis = a;
      const normal = [0, 0, 0];
      normal[axis] = f[axis] > 0 ? -1 : 1;
      out.push({ point: camera.target.slice(), normal });
      return out;
    }
    case 'j':
      if (last)
        last.normal = last.normal.map(x => -x);
      return out;
    case '9':
    case '0': {
      if (!last || !(boxSide > 0))
        return out;
      const m = last.normal, len = Math.hypot(...m), step = (k === '0' ? 1 : -1) * boxSide / 50;
      last.point = last.point.map((p, a) => p + step * m[a] / len);
      return out;
    }
    case 'i':
      out.pop();
      return out;
    default:
      return null;
    }
  }

  // meshview's HUD line: "section z=-0.005", "sections ...", a free plane
  // "at PX,PY,PZ normal NX,NY,NZ".
  function describe(list) {
    const g = (x, p) => Number(x.toPrecision(p)).toString();
    return list.map((s, k) => {
      const lead = k ? '  ' : list.length > 1 ? 'sections ' : 'section ';
      const m = s.normal;
      const axis = [0, 1, 2].find(a => m[a] !== 0 && m[(a + 1) % 3] === 0 && m[(a + 2) % 3] === 0);
      if (axis !== undefined)
        return lead + (m[axis] < 0 ? '-' : '') + 'xyz'[axis] + '=' + g(s.point[axis], 4);
      return lead + 'at ' + s.point.map(x => g(x, 4)).join(',') + ' normal ' + m.map(x => g(x, 3)).join(',');
    }).join('');
  }

  return { MAX, COLOUR, planes, key, describe };
})();
