// The viewer page (/view/NAME#cam=...): decodes in a Web Worker (worker.js)
// and draws the stitched cut with WebGL 2 (docs/BROWSER.md). The URL's hash
// holds the camera, so a view can be shared:
//   #cam=PX,PY,PZ,TX,TY,TZ,UX,UY,UZ,FOVY   position, target, up, degrees
//   &tol=PIXELS                             screen tolerance (default 1)
//   &culled=BITS                            bits given up outside the view (default 6)
//   &mem=MB                                 received streams kept at most (docs/BROWSER.md "Memory")
//   &hud=0                                  no overlay (pictures for tests)
// The token is asked once, kept for the tab (sessionStorage) and sent as
// Authorization by the worker, never in a URL. window.meshstream holds the
// page's state for scripts: state ('loading', 'complete', 'error'), message,
// triangles, cells, bits (the finest shown), bytes, firstPixelMs, completeMs,
// workerMs (when the worker was started; the worker's own marks in timing
// count from there), all in ms from the navigation.
'use strict';

const boot = window.meshstreamBoot;   // boot.js, in the page's head
const TOKEN_KEY = boot.tokenKey;
const page = { state: 'loading', message: '', triangles: 0, cells: 0, bits: 0, bytes: 0,
               firstPixelMs: null, completeMs: null, workerMs: null };
window.meshstream = page;

const canvas = document.getElementById('view');
const statusLine = document.getElementById('status');
const progress = document.getElementById('progress');
const figures = document.getElementById('figures');
const shareLine = document.getElementById('share');

function say(text, isError) {
  statusLine.textContent = text;
  statusLine.className = isError ? 'error' : '';
  page.message = text;
}

// In a frame of another page (web/embed.js), that page hears how the view
// goes: {meshstream: a copy of window.meshstream} at each round, view
// complete and error. The state holds no token and no model bytes.
function tellEmbedder() {
  if (window.parent !== window)
    window.parent.postMessage({ meshstream: Object.assign({}, page) }, '*');
}

function failPage(text) {
  say(text, true);
  page.state = 'error';
  tellEmbedder();
}

// ---- URL: model and camera -------------------------------------------------

// Two layouts of the same pages: meshserve's /view/NAME, and a static
// export's view/NAME.html (meshexport --web-dir; docs/BROWSER.md): the worker
// reads the model where the layout keeps it. Every other path is relative,
// so a site may live under any folder of its server.
const staticSite = boot.staticSite;
const name = boot.name;
const hash = new URLSearchParams(location.hash.slice(1));
document.getElementById('model').textContent = name;
document.title = name + ' · meshstream';
if (hash.get('hud') === '0')
  document.getElementById('hud').className = 'hidden';

function parseCamera(text) {
  if (!text)
    return null;
  const v = text.split(',').map(Number);
  if (v.length !== 10 || v.some(x => !Number.isFinite(x)))
    return null;
  return { position: v.slice(0, 3), target: v.slice(3, 6), up: v.slice(6, 9), fovy: v[9] };
}

let camera = parseCamera(hash.get('cam'));   // or #view=mv1:..., read in start()
const tolerance = Number(hash.get('tol')) > 0 ? Number(hash.get('tol')) : 1;
// bits given up outside the view: the client core's 6 unless the URL says
const culled = hash.get('culled') !== null && Number(hash.get('culled')) >= 0 ? Number(hash.get('culled')) : 6;
// the memory budget, MB of received streams the worker keeps (docs/BROWSER.md
// "Memory"): 64 MB a GB of the device's memory (navigator.deviceMemory, 4 GB
// where the browser does not say), 16 to 1024 MB; #mem=MB says otherwise
const memoryMb = Number(hash.get('mem')) > 0 ? Math.min(Number(hash.get('mem')), 4095)
  : Math.min(1024, Math.max(16, 64 * (navigator.deviceMemory || 4)));
if (hash.get('cam') && !parseCamera(hash.get('cam')))
  failPage('The camera in the URL is not ten numbers (#cam=PX,PY,PZ,TX,TY,TZ,UX,UY,UZ,FOVY).');


// ---- Small vector and matrix helpers (column-major 4x4) ---------------------

const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const norm = a => { const l = Math.hypot(...a); return [a[0] / l, a[1] / l, a[2] / l]; };

const viewProjection = MsCamera.viewProjection; // web/camera.js

// ---- WebGL 2: meshview's shaders (web/render.js) ----------------------------
// The shading mode: meshview's --shading apo (the default: lit, with the APO
// normals where a cell's chunk came), geometry (lit, no APO: none fetched),
// normals or cells (with APO as apo), from #shading= or the HUD's control
// (its N and C keys toggle normals and cells, as meshview's); the URL keeps
// it when it is not the default. The worker fetches APO chunks only for a
// mode that draws them (docs/BROWSER.md, "APO").

const SHADING_NAMES = Object.keys(MsRender.MODES);
let shading = 'apo';
if (hash.get('shading') !== null) {
  if (SHADING_NAMES.includes(hash.get('shading')))
    shading = hash.get('shading');
  else
    failPage('The shading in the URL is not one of ' + SHADING_NAMES.join(', ') + ' (#shading=MODE).');
}
page.shading = shading;

// The WebGL 2 context, made once the worker runs (startGl): null before.
let gl = null;
let indexCount = 0, box = null, frameRequested = false, lastSentApo = false, completeWaiting = null;

function setUpGl() {
  MsRender.setUp(gl);
}

function setShading(mode) {
  if (!SHADING_NAMES.includes(mode) || mode === shading)
    return;
  shading = mode;
  page.shading = mode;
  shadingControl.value = mode;
  if (mode === 'apo')
    hash.delete('shading');
  else
    hash.set('shading', mode);
  history.replaceState(null, '', '#' + MsTools.hashString(hash));
  if (worker && box && camera && MsRender.usesApo(mode) && !lastSentApo)
    worker.postMessage({ type: 'camera', camera: workerCamera() });   // the chunks, now wanted
  requestDraw();
}

const shadingControl = document.getElementById('shading');
shadingControl.value = shading;
shadingControl.addEventListener('change', () => setShading(shadingControl.value));
window.addEventListener('keydown', e => {
  if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement || e.ctrlKey ||
      e.metaKey || e.altKey)
    return;
  const k = e.key.toLowerCase(), mode = k === 'n' ? 'normals' : k === 'c' ? 'cells' : null;
  if (mode) {
    setShading(shading === mode ? 'apo' : mode);   // meshview's toggle
    e.preventDefault();
  }
});

function resize() {
  const ratio = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * ratio));
  const h = Math.max(1, Math.round(canvas.clientHeight * ratio));
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w;
    canvas.height = h;
  }
}

// Clipping planes that frame the model's box from where the camera is.
function depthRange() {
  let far = 0, near = Infinity;
  for (let corner = 0; corner < 8; ++corner) {
    const p = [0, 1, 2].map(a => box[a] + ((corner >> a) & 1 ? box[3] : 0));
    const d = Math.hypot(...sub(p, camera.position));
    far = Math.max(far, d);
    near = Math.min(near, d);
  }
  far *= 1.01;
  const inside = [0, 1, 2].every(a => camera.position[a] >= box[a] && camera.position[a] <= box[a] + box[3]);
  near = inside ? far * 1e-4 : Math.max(far * 1e-4, 0.5 * near - box[3]);
  return [Math.max(near, far * 1e-4), far];
}

// The page's own share of the time (window.meshstream.timing, beside the
// worker's): seconds uploading meshes and issuing frames, and their counts.
const pageTiming = { upload: 0, draw: 0, meshes: 0, frames: 0 };

function draw() {
  const t = performance.now();
  try {
    drawFrame();
  } finally {
    pageTiming.draw += (performance.now() - t) / 1000;
  }
}

function drawFrame() {
  frameRequested = false;
  if (!gl)
    return;                 // startGl draws once the context is made
  resize();
  const ready = indexCount && camera && box;
  const [near, far] = ready ? depthRange() : [1, 2];
  const drawn = MsRender.draw(Object.assign(MsTools.lighting(), {
    camera: ready ? camera : null, width: canvas.width, height: canvas.height, near, far,
    mode: MsRender.MODES[shading], shading }));
  page.apo = Object.assign({}, MsRender.apoStats, { waiting: drawn.waiting });
  page.upload = MsRender.meshStats;
  if (drawn.waiting)
    requestDraw();          // a mesh or APO texels beyond this frame's upload budget
  else if (completeWaiting) {
    const m = completeWaiting;
    completeWaiting = null;
    complete(m);
  }
  if (!ready || !drawn.cells)
    return;
  pageTiming.frames++;
  MsTools.drawn(camera);
  if (typeof annotationsOnDraw === 'function')   // web/annotations.js: the markers
    annotationsOnDraw();
  if (page.firstPixelMs === null)
    page.firstPixelMs = Math.round(performance.now());
}

function requestDraw() {
  if (!frameRequested) {
    frameRequested = true;
    requestAnimationFrame(draw);
  }
}

function upload(m) {
  const t = performance.now();
  pageTiming.meshes++;
  MsRender.upload(m);
  indexCount = m.triangles.length;
  pageTiming.upload += (performance.now() - t) / 1000;
  if (typeof annotationsOnMesh === 'function')   // web/annotations.js: occlusion
    annotationsOnMesh(m.positions, m.triangles);
}

// ---- Camera: home, orbit, zoom, the URL ------------------------------------

// The whole model in view: its bounds (lo, hi) when the root told them, else
// its cubic box (origin, side).
function homeCamera(b, bounds) {
  const lo = bounds ? bounds.slice(0, 3) : b.slice(0, 3);
  const hi = bounds ? bounds.slice(3, 6) : b.slice(0, 3).map(x => x + b[3]);
  const fovy = 40, centre = [0, 1, 2].map(a => (lo[a] + hi[a]) / 2);
  const radius = Math.hypot(...sub(hi, lo)) / 2;
  const distance = 1.05 * radius / Math.sin(fovy * Math.PI / 360);
  const dir = norm([Math.sin(0.35), 0.25, Math.cos(0.35)]);
  return { position: centre.map((c, a) => c + distance * dir[a]), target: centre, up: [0, 1, 0], fovy };
}

function cameraText(c) {
  return [...c.position, ...c.target, ...c.up, c.fovy].map(x => +x.toPrecision(7)).join(',');
}

let worker = null, cameraTimer = null;

function cameraMoved() {
  requestDraw();
  if (cameraTimer)
    return;
  cameraTimer = setTimeout(() => {
    cameraTimer = null;
    MsTools.toHash(hash);   // #cam=, or #view= with the light, planes, points
    history.replaceState(null, '', '#' + MsTools.hashString(hash));
    showShare();
    worker.postMessage({ type: 'camera', camera: workerCamera() });
  }, 100);
}

// ---- Controls: meshview's (client/view/ms_viewer_controls.c) --------------
// A turntable about the camera's up: yaw and pitch (at most 89 degrees), pi
// radians per canvas height; pan moves the target in the view plane, a pixel
// a pixel at the target's depth; zoom scales the distance by 0.85 a step.
// Mouse: drag to orbit, right or middle drag (or shift drag) to pan, wheel to
// zoom. Touch: one finger orbits, two pinch to zoom and move to pan.

// The frame of an up vector: up, and two horizontal axes with yaw 0 looking
// along -h0; for a coordinate axis meshview's (y up: h0 = z, h1 = x; z up:
// h0 = y, h1 = z + 1 = x).
function upFrame(up) {
  const u = norm(up);
  const axis = [0, 1, 2].find(a => Math.abs(u[a]) > 1 - 1e-12 && u[a] > 0);
  if (axis !== undefined) {
    const h0 = [0, 0, 0], h1 = [0, 0, 0];
    h0[(axis + 2) % 3] = 1;
    h1[(axis + 1) % 3] = 1;
    return { up: u, h0, h1, axis };
  }
  const h1 = norm(cross(u, Math.abs(u[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0]));
  return { up: u, h0: cross(h1, u), h1, axis: undefined };
}

const PITCH_LIMIT = 89 * Math.PI / 180;

// The camera as meshview's controller state: target, distance, yaw, pitch.
function orbitState(c) {
  const fr = upFrame(c.up), f = sub(c.target, c.position);
  const a = -dot(f, fr.h0), b = -dot(f, fr.h1), u = dot(f, fr.up);
  const horizontal = Math.hypot(a, b);
  return { frame: fr, distance: Math.hypot(...f), yaw: horizontal > 0 ? Math.atan2(b, a) : 0,
           pitch: Math.max(-PITCH_LIMIT, Math.min(PITCH_LIMIT, Math.atan2(u, horizontal))) };
}

function forwardOf(fr, yaw, pitch) {
  const cp = Math.cos(pitch), sp = Math.sin(pitch), cy = Math.cos(yaw), sy = Math.sin(yaw);
  return [0, 1, 2].map(k => -cp * (cy * fr.h0[k] + sy * fr.h1[k]) + sp * fr.up[k]);
}

function placeCamera(st, target) {
  const f = forwardOf(st.frame, st.yaw, st.pitch);
  camera.target = target;
  camera.position = target.map((t, k) => t - st.distance * f[k]);
  camera.up = st.frame.up;
}

function orbit(dx, dy) {
  const st = orbitState(camera), perPixel = Math.PI / Math.max(canvas.clientHeight, 1);
  st.yaw = Math.atan2(Math.sin(st.yaw + dx * perPixel), Math.cos(st.yaw + dx * perPixel));
  st.pitch = Math.max(-PITCH_LIMIT, Math.min(PITCH_LIMIT, st.pitch - dy * perPixel));
  placeCamera(st, camera.target);
  cameraMoved();
}

function pan(dx, dy) {
  const f = norm(sub(camera.target, camera.position));
  const right = norm(cross(f, camera.up)), camUp = cross(right, f);
  const distance = Math.hypot(...sub(camera.target, camera.position));
  const perPixel = 2 * distance * Math.tan(camera.fovy * Math.PI / 360) / Math.max(canvas.clientHeight, 1);
  const move = [0, 1, 2].map(k => (-dx * right[k] + dy * camUp[k]) * perPixel);
  camera.target = camera.target.map((t, k) => t + move[k]);
  camera.position = camera.position.map((p, k) => p + move[k]);
  cameraMoved();
}

function zoom(factor) {
  camera.position = camera.target.map((t, a) => t + (camera.position[a] - t) * factor);
  cameraMoved();
}

// Pointers down on the canvas (mouse, pen, fingers), by id: where each was.
const pointers = new Map();
let panning = false, pinch = null;

function pinchState() {
  const [a, b] = [...pointers.values()];
  return { gap: Math.hypot(a[0] - b[0], a[1] - b[1]), mid: [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2] };
}

canvas.addEventListener('contextmenu', e => e.preventDefault());
canvas.addEventListener('pointerdown', e => {
  canvas.setPointerCapture(e.pointerId);
  pointers.set(e.pointerId, [e.clientX, e.clientY]);
  panning = e.button === 1 || e.button === 2 || e.shiftKey;
  pinch = pointers.size === 2 ? pinchState() : null;
});
const lift = e => {
  pointers.delete(e.pointerId);
  pinch = pointers.size === 2 ? pinchState() : null;
};
canvas.addEventListener('pointerup', lift);
canvas.addEventListener('pointercancel', lift);
canvas.addEventListener('pointermove', e => {
  const was = pointers.get(e.pointerId);
  if (!was || !camera)
    return;
  pointers.set(e.pointerId, [e.clientX, e.clientY]);
  if (pointers.size === 2 && pinch) {
    const now = pinchState();
    if (now.gap > 0 && pinch.gap > 0)
      zoom(pinch.gap / now.gap);
    pan(now.mid[0] - pinch.mid[0], now.mid[1] - pinch.mid[1]);
    pinch = now;
  } else if (pointers.size === 1) {
    const dx = e.clientX - was[0], dy = e.clientY - was[1];
    if (panning)
      pan(dx, dy);
    else
      orbit(dx, dy);
  }
});
canvas.addEventListener('wheel', e => {
  e.preventDefault();
  if (camera)
    zoom(Math.pow(0.85, -e.deltaY / 100));
}, { passive: false });

// ---- meshview's view text (client/view/ms_viewer_share.h) -------------------
// mv1:t=X,Y,Z:d=D:o=YAW,PITCH:f=FOVY:u=AXIS[:l=...][:s=...][:m=...]: the page
// takes all of it (share.js; the light, planes and points into tools.js), and
// shows the text of its view when its up is a coordinate axis.

function parseShare(text) {
  return MsTools.fromView(text);
}

// The view's text, as meshview prints it (share.js).
function shareText(c) {
  return MsTools.viewText(c);
}

window.addEventListener('resize', () => { if (camera && worker) cameraMoved(); requestDraw(); });

// Each camera the worker gets is numbered: a 'complete' for an earlier one
// (crossing the new camera on its way) leaves the page loading.
let cameraSeq = 0, cameraSentAt = 0;

function workerCamera() {
  resize();
  if (page.state !== 'error')
    page.state = 'loading';
  cameraSentAt = performance.now();
  lastSentApo = MsRender.usesApo(shading);
  completeWaiting = null;
  return Object.assign({}, camera, { width: canvas.width, height: canvas.height, tolerance,
                                     seq: ++cameraSeq, apo: MsRender.usesApo(shading) });
}

// A camera typed or pasted into the URL's hash (or set by a script, as the
// tests do along a camera path) moves the view there.
window.addEventListener('hashchange', () => {
  const next = new URLSearchParams(location.hash.slice(1));
  const c = parseCamera(next.get('cam')) || parseShare(next.get('view'));
  if (!c || !worker || !box || (camera && cameraText(c) === cameraText(camera)))
    return;
  camera = c;
  hash.set('cam', cameraText(camera));
  worker.postMessage({ type: 'camera', camera: workerCamera() });
  requestDraw();
});

// ---- The HUD: figures and the view's text ---------------------------------

function showFigures() {
  const parts = [page.triangles.toLocaleString('en') + ' triangles', page.cells + ' cells',
                 'up to ' + page.bits + ' bits', (page.bytes / 1e3).toFixed(0) + ' kB',
                 'round ' + (page.rounds || 0)];
  const apoCells = Object.keys(MsRender.apoStats.levels).length;
  if (apoCells && MsRender.usesApo(shading))
    parts.push('APO normals in ' + apoCells + (apoCells === 1 ? ' cell' : ' cells'));
  if (page.firstPixelMs !== null)
    parts.push('first pixels ' + page.firstPixelMs + ' ms');
  if (page.state === 'complete')
    parts.push('complete ' + page.settleMs + ' ms after the camera');
  figures.textContent = parts.join(' · ');
}

function showShare() {
  const text = camera ? shareText(camera) : null;
  page.view = text;
  shareLine.textContent = text || '';
}

// ---- The token -----------------------------------------------------------

document.getElementById('token-form').addEventListener('submit', e => {
  e.preventDefault();
  const value = document.getElementById('token').value.trim();
  if (value)
    sessionStorage.setItem(TOKEN_KEY, value);
  else
    sessionStorage.removeItem(TOKEN_KEY);
  location.reload();
});

// ---- The worker ----------------------------------------------------------

// View complete: the worker's last mesh and APO texels are drawn (the
// renderer's upload budget may take a few frames after the worker's message).
function complete(m) {
  page.bytes = m.bytes;
  page.rounds = m.rounds;
  page.timing = Object.assign({}, m.timing, pageTiming);
  page.completeMs = Math.round(performance.now());
  page.settleMs = Math.round(performance.now() - cameraSentAt);  // from this camera
  page.state = 'complete';
  page.progress = 1;
  progress.value = 1;
  showFigures();
  showShare();
  say(name + ': ' + page.triangles.toLocaleString('en') + ' triangles in ' + page.cells +
      ' cells, up to ' + page.bits + ' bits, ' + (m.bytes / 1e3).toFixed(0) + ' kB, view complete' +
      (m.preview ? (staticSite ? ' (the public preview)' : ' (the public preview: a token gives more)') : ''));
  tellEmbedder();
}

function start() {
  // The worker was started by boot.js in the page's head: it compiles the
  // module and fetches the index already, while the page loads and WebGL
  // compiles its program (its messages come after this task ends).
  if (!camera && hash.get('view')) {
    camera = parseShare(hash.get('view'));
    if (!camera)
      failPage('The view in the URL is not meshview\'s text: ' + MsTools.viewError() + '.');
  }
  if (page.state === 'error') {
    boot.worker.terminate();
    return;
  }
  say('Loading ' + name + '…');
  worker = boot.worker;
  page.workerMs = Math.round(boot.at);
  worker.onerror = e => failPage('The decoder failed: ' + (e.message || 'the worker did not start'));
  worker.onmessage = e => {
    const m = e.data;
    if (!gl && GL_MESSAGES.has(m.type)) {
      early.push(m);        // drawn once the context is made (startGl)
      return;
    }
    handle(m);
  };
  worker.postMessage({ type: 'start', name, token: sessionStorage.getItem(TOKEN_KEY) || '', culled,
                       memory: Math.max(1, Math.floor(memoryMb * 1048576)),
                       layout: staticSite ? 'static' : 'door',
                       camera: camera ? workerCamera() : null });
  (boot.ready || Promise.resolve()).then(startGl);
}

// The worker's messages that need the context, and those that came before it.
const GL_MESSAGES = new Set(['mesh', 'apo', 'complete']);
const early = [];

// The context, made after the worker's start (boot.js's ready): the worker
// plans and decodes its first look meanwhile.
function startGl() {
  if (page.state === 'error')
    return;
  gl = canvas.getContext('webgl2', { antialias: false });
  if (!gl) {
    worker.terminate();
    failPage('This browser offers no WebGL 2: the model cannot be drawn.');
    return;
  }
  try {
    setUpGl();
  } catch (e) {
    gl = null;
    worker.terminate();
    failPage('WebGL 2 failed: ' + e.message);
    return;
  }
  pageTiming.glMs = Math.round(performance.now());   // boot.js: made after the worker's start
  pageTiming.aliveMs = boot.aliveAt;
  pageTiming.glAfter = boot.readyBy;
  MsTools.started();
  for (const m of early.splice(0))
    handle(m);
  requestDraw();
}

// One message of the worker's.
function handle(m) {
  if (MsTools.message(m))
    return;               // the tools' (casts)
  if (m.type === 'box') {
    box = m.box;
    if (!camera) {
      camera = homeCamera(box, m.bounds);
      worker.postMessage({ type: 'camera', camera: workerCamera() });
    }
  } else if (m.type === 'progress') {
    page.bytes = m.bytes;
    page.rounds = m.rounds;
    // received over received plus what this round still wants (the next
    // round's plan is not known yet: the bar fills once per round)
    page.progress = m.bytes / Math.max(m.bytes + m.need, 1);
    progress.value = page.progress;
    say('Loading ' + name + ': ' + (m.bytes / 1e3).toFixed(0) + ' kB, ' + m.wanted + ' cells wanted');
    showFigures();
    tellEmbedder();
  } else if (m.type === 'mesh') {
    upload(m);
    page.triangles = m.triangles.length / 3;
    page.cells = m.cells;
    page.bits = m.bits;
    showFigures();
    requestDraw();
    MsTools.recast();     // measuring points follow the finer surface
  } else if (m.type === 'apo') {
    MsRender.apoChunk(m);
    requestDraw();
  } else if (m.type === 'complete') {
    if (m.seq !== cameraSeq)
      return;              // an earlier camera's; the latest one is under way
    if (MsRender.pending()) {
      completeWaiting = m; // complete once its mesh and texels are up (drawFrame)
      requestDraw();
    } else {
      complete(m);
    }
  } else if (m.type === 'error') {
    failPage(m.message.charAt(0).toUpperCase() + m.message.slice(1));
  }
}

start();
