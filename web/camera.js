// The camera's matrices for the pages (view.js, render.js, annotations.js
// through view.js, and the Draco page): a look-at view and an OpenGL
// perspective projection from a camera {position, target, up, fovy (degrees)}
// and the picture's size and clipping planes, as meshview's
// (common/camera/ms_camera.c). Column-major, as WebGL takes them.
'use strict';

const MsCamera = (() => {
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = a => { const l = Math.hypot(...a); return [a[0] / l, a[1] / l, a[2] / l]; };

  // {view, proj}: two arrays of 16 numbers.
  function matrices(c, width, height, near, far) {
    const f = norm(sub(c.target, c.position));
    const r = norm(cross(f, c.up));
    const u = cross(r, f);
    const view = [r[0], u[0], -f[0], 0, r[1], u[1], -f[1], 0, r[2], u[2], -f[2], 0,
                  -dot(r, c.position), -dot(u, c.position), dot(f, c.position), 1];
    const t = 1 / Math.tan(c.fovy * Math.PI / 360), a = width / height;
    const proj = [t / a, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) / (near - far), -1,
                  0, 0, 2 * far * near / (near - far), 0];
    return { view, proj };
  }

  // proj x view as a Float32Array.
  function viewProjection(c, width, height, near, far) {
    const { view, proj } = matrices(c, width, height, near, far);
    const m = new Float32Array(16);
    for (let i = 0; i < 4; ++i)
      for (let j = 0; j < 4; ++j) {
        let s = 0;
        for (let k = 0; k < 4; ++k)
          s += proj[k * 4 + j] * view[i * 4 + k];
        m[i * 4 + j] = s;
      }
    return m;
  }

  return { matrices, viewProjection };
})();
