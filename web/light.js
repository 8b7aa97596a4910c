// The page's light (docs/BROWSER.md, "Light"), meshview's
// (client/view/ms_viewer_light.h): the head light by default (at the eye,
// shining where it looks); once moved, a directional light given in the
// camera's frame by azimuth and elevation in degrees, so it stays where it
// is on the screen while the camera orbits. In eye space (x right, y up, z
// towards the viewer) it shines from (cos el sin az, sin el, cos el cos az).
// Ctrl (or Alt) + drag moves it: half a turn of azimuth across the canvas's
// height, the elevation following the cursor, clamped at the poles. L (or
// the light button) steps through the raking presets: 80 degrees from the
// view axis from the left, the top, the right, the bottom, then the head
// light. A light is null (the head light) or {az, el}.
'use strict';

const MsLight = (() => {
  const DEG = Math.PI / 180;
  const PRESETS = [[-80, 0], [0, 80], [80, 0], [0, -80]];

  function eye(l) {
    const az = l ? l.az * DEG : 0, el = l ? l.el * DEG : 0;
    return [Math.cos(el) * Math.sin(az), Math.sin(el), Math.cos(el) * Math.cos(az)];
  }

  // Towards the light in world coordinates, for a camera {position, target, up}.
  function world(l, c) {
    const f = [0, 1, 2].map(a => c.target[a] - c.position[a]);
    const fl = Math.hypot(...f), fw = f.map(x => x / fl);
    const r = [fw[1] * c.up[2] - fw[2] * c.up[1], fw[2] * c.up[0] - fw[0] * c.up[2],
               fw[0] * c.up[1] - fw[1] * c.up[0]];
    const rl = Math.hypot(...r), right = r.map(x => x / rl);
    const up = [right[1] * fw[2] - right[2] * fw[1], right[2] * fw[0] - right[0] * fw[2],
                right[0] * fw[1] - right[1] * fw[0]];
    const e = eye(l);
    return [0, 1, 2].map(a => e[0] * right[a] + e[1] * up[a] - e[2] * fw[a]);
  }

  function drag(l, dx, dy, height) {
    if (!(height > 0) || !Number.isFinite(dx) || !Number.isFinite(dy))
      return l;
    const from = l || { az: 0, el: 0 };
    let az = from.az + 180 * dx / height, el = from.el - 180 * dy / height;
    az = az % 360;            // as C's fmod: the sign of the dividend
    if (az > 180)
      az -= 360;
    else if (az <= -180)
      az += 360;
    return { az, el: Math.max(-90, Math.min(90, el)) };
  }

  function nextPreset(l) {
    let next = 0;
    if (l) {
      next = 4;
      PRESETS.forEach((p, i) => { if (l.az === p[0] && l.el === p[1]) next = i + 1; });
    }
    return next === 4 ? null : { az: PRESETS[next][0], el: PRESETS[next][1] };
  }

  function describe(l) {
    return l ? 'light az ' + l.az.toFixed(1) + ' el ' + l.el.toFixed(1) + ' deg' : 'head light';
  }

  return { eye, world, drag, nextPreset, describe };
})();
