// The model's annotations in the viewer page (docs/ANNOTATIONS.md,
// docs/BROWSER.md "Annotations"): fetched from the side door
// (models/NAME/annotations; a static export's file models/NAME/annotations.json,
// which meshexport writes where the model has any), 404 meaning none; each a marker (an HTML button over the canvas, at the
// pixel its point projects to, so it always faces the camera), hidden when
// the drawn surface is in front of it; a click shows its title and text (as
// text, never as HTML) and moves the camera to the view stored with it
// (meshview's view text), or centres the orbit on its point. #annotation=ID
// in the URL selects one at the start, and the page keeps it there.
//
// Occlusion is a ray test on the CPU against the mesh the page draws: the
// segment from the eye to the point must not cross a triangle nearer than
// the point less max(radius, 1% of its distance) (meshview's allowance),
// where no section plane cuts the surface away. It
// runs 150 ms after the camera or the mesh last changed (markers keep their
// last answer while the camera moves), and not at all when annotations times
// triangles pass 4e7 (markers then all shown; window.meshstream.annotations
// .occlusion says 'skipped').
//
// Uses view.js's globals (a classic script loaded after it): camera, canvas,
// box, hash, name, staticSite, TOKEN_KEY, depthRange, viewProjection,
// orbitState, placeCamera, upFrame, forwardOf, cameraMoved, requestDraw,
// page; and share.js's MsShare.parse. view.js calls annotationsOnMesh and
// annotationsOnDraw.
'use strict';

const annotations = {
  list: [], markers: [], seen: [], selected: -1, mesh: null, timer: null, moving: null, pending: null,
  report: { state: 'loading', count: 0, markers: [], selected: null, title: null, text: null,
            occlusion: 'none', scripts: document.scripts.length, pwned: null },
};
page.annotations = annotations.report;

const MOVE_MS = 800;
const RAY_BUDGET = 4e7;   // annotations x triangles a test may cost

const layer = document.createElement('div');
layer.id = 'annotations';
Object.assign(layer.style, { position: 'fixed', left: '0', top: '0', width: '100vw', height: '100vh',
                             pointerEvents: 'none', overflow: 'hidden' });
document.body.appendChild(layer);

const panel = document.createElement('div');
panel.id = 'annotation-panel';
Object.assign(panel.style, { position: 'fixed', left: '0.5em', bottom: '0.5em', maxWidth: '32em',
                             padding: '0.4em 0.6em', background: 'rgba(0, 0, 0, 0.7)', borderRadius: '4px',
                             display: 'none', whiteSpace: 'pre-line' });
const panelTitle = document.createElement('div');
panelTitle.id = 'annotation-title';
panelTitle.style.fontWeight = 'bold';
panelTitle.style.color = '#fa3';
const panelText = document.createElement('div');
panelText.id = 'annotation-text';
panel.append(panelTitle, panelText);
document.body.appendChild(panel);

// A list read from the file, keeping only well-formed annotations (the
// server checked the file; a static site may not have).
function readAnnotations(json) {
  const list = json && json.format === 'meshstream-annotations' && Array.isArray(json.annotations)
    ? json.annotations : [];
  return list.filter(a => a && typeof a.id === 'string' && typeof a.title === 'string' &&
                          Array.isArray(a.point) && a.point.length === 3 && a.point.every(Number.isFinite))
    .map(a => ({ id: a.id, point: a.point, title: a.title, text: typeof a.text === 'string' ? a.text : '',
                 radius: Number.isFinite(a.radius) && a.radius > 0 ? a.radius : 0,
                 view: typeof a.view === 'string' ? a.view : null }));
}

function makeMarkers() {
  layer.replaceChildren();
  annotations.markers = annotations.list.map((a, i) => {
    const m = document.createElement('button');
    m.className = 'annotation-marker';
    m.title = a.title;                      // a property: text, not markup
    m.setAttribute('aria-label', a.title);
    m.dataset.id = a.id;
    Object.assign(m.style, { position: 'absolute', width: '14px', height: '14px', margin: '-7px 0 0 -7px',
                             padding: '0', border: '2px solid #111', borderRadius: '50%',
                             background: '#3df', cursor: 'pointer', pointerEvents: 'auto', display: 'none' });
    m.addEventListener('click', e => { e.stopPropagation(); selectAnnotation(i, true); });
    layer.appendChild(m);
    return m;
  });
  annotations.seen = annotations.list.map(() => true);
}

async function loadAnnotations() {
  const path = 'models/' + encodeURIComponent(name) + (staticSite ? '/annotations.json' : '/annotations');
  const headers = {};
  const token = sessionStorage.getItem(TOKEN_KEY);
  if (token)
    headers.Authorization = 'Bearer ' + token;
  try {
    const answer = await fetch(new URL(path, new URL('../', location.href)).href, { headers });
    if (answer.status === 404) {
      annotations.report.state = 'none';
      return;
    }
    if (!answer.ok)
      throw new Error('HTTP ' + answer.status);
    annotations.list = readAnnotations(await answer.json());
  } catch (e) {
    annotations.report.state = 'error';
    annotations.report.message = 'annotations: ' + e.message;
    return;
  }
  annotations.report.state = 'loaded';
  annotations.report.count = annotations.list.length;
  makeMarkers();
  // #annotation=ID: selected; the camera goes to its view unless the URL sets one
  const wanted = annotations.list.findIndex(a => a.id === hash.get('annotation'));
  if (wanted >= 0)
    selectAnnotation(wanted, !hash.get('cam') && !hash.get('view'));
  scheduleOcclusion();
  requestDraw();
}

// ---- projection and occlusion ---------------------------------------------

// CSS pixels of world point p in the canvas, or null behind the eye.
function projectPoint(p, matrix) {
  const x = matrix[0] * p[0] + matrix[4] * p[1] + matrix[8] * p[2] + matrix[12];
  const y = matrix[1] * p[0] + matrix[5] * p[1] + matrix[9] * p[2] + matrix[13];
  const w = matrix[3] * p[0] + matrix[7] * p[1] + matrix[11] * p[2] + matrix[15];
  if (!(w > 0))
    return null;
  const r = canvas.getBoundingClientRect();
  return [r.left + (x / w + 1) / 2 * r.width, r.top + (1 - y / w) / 2 * r.height];
}

// Whether the page's section planes (tools.js: window.meshstream.sections,
// each a point and the normal of the side cut away) cut point h away.
function cutAway(h) {
  return (page.sections || []).some(q => (h[0] - q.point[0]) * q.normal[0] + (h[1] - q.point[1]) * q.normal[1] +
                                         (h[2] - q.point[2]) * q.normal[2] > 0);
}

// Whether the segment from the eye to p crosses the mesh before p, less the allowance.
function occluded(p, radius, positions, triangles) {
  const e = camera.position, d = [p[0] - e[0], p[1] - e[1], p[2] - e[2]];
  const dp = Math.hypot(...d), limit = (dp - Math.max(radius, 0.01 * dp)) / dp;
  if (!(limit > 0))
    return false;
  for (let t = 0; t < triangles.length; t += 3) {
    const a = 3 * triangles[t], b = 3 * triangles[t + 1], c = 3 * triangles[t + 2];
    const e1x = positions[b] - positions[a], e1y = positions[b + 1] - positions[a + 1], e1z = positions[b + 2] - positions[a + 2];
    const e2x = positions[c] - positions[a], e2y = positions[c + 1] - positions[a + 1], e2z = positions[c + 2] - positions[a + 2];
    const px = d[1] * e2z - d[2] * e2y, py = d[2] * e2x - d[0] * e2z, pz = d[0] * e2y - d[1] * e2x;
    const det = e1x * px + e1y * py + e1z * pz;
    if (Math.abs(det) < 1e-30)
      continue;
    const inv = 1 / det, sx = e[0] - positions[a], sy = e[1] - positions[a + 1], sz = e[2] - positions[a + 2];
    const u = (sx * px + sy * py + sz * pz) * inv;
    if (u < 0 || u > 1)
      continue;
    const qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
    const v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv;
    if (v < 0 || u + v > 1)
      continue;
    const s = (e2x * qx + e2y * qy + e2z * qz) * inv;
    if (s > 1e-9 && s < limit && !cutAway([e[0] + s * d[0], e[1] + s * d[1], e[2] + s * d[2]]))
      return true;
  }
  return false;
}

function testOcclusion() {
  annotations.timer = null;
  const mesh = annotations.mesh;
  if (!mesh || !camera || !annotations.list.length)
    return;
  if (annotations.list.length * mesh.triangles.length / 3 > RAY_BUDGET) {
    annotations.seen = annotations.list.map(() => true);
    annotations.report.occlusion = 'skipped';
  } else {
    annotations.seen = annotations.list.map(a => !occluded(a.point, a.radius, mesh.positions, mesh.triangles));
    annotations.report.occlusion = 'tested';
  }
  placeMarkers();
}

function scheduleOcclusion() {
  if (annotations.timer)
    clearTimeout(annotations.timer);
  annotations.timer = setTimeout(testOcclusion, 150);
}

function placeMarkers() {
  if (!camera || !box || !annotations.markers.length)
    return;
  const [near, far] = depthRange();
  const matrix = viewProjection(camera, canvas.width, canvas.height, near, far);
  annotations.report.markers = annotations.list.map((a, i) => {
    const at = projectPoint(a.point, matrix), m = annotations.markers[i];
    const seen = !!at && annotations.seen[i] && at[0] >= 0 && at[1] >= 0 &&
                 at[0] < window.innerWidth && at[1] < window.innerHeight;
    m.style.display = seen ? 'block' : 'none';
    m.style.background = i === annotations.selected ? '#fa3' : '#3df';
    if (at) {
      m.style.left = at[0] + 'px';
      m.style.top = at[1] + 'px';
    }
    return { id: a.id, x: at ? at[0] : null, y: at ? at[1] : null, seen };
  });
}

// ---- selection and the camera's move ----------------------------------------

function selectAnnotation(i, move) {
  const a = annotations.list[i];
  annotations.selected = i;
  panelTitle.textContent = a.title;
  panelText.textContent = a.text;
  panel.style.display = 'block';
  // what the panel shows, read back; for the tests, the page's script elements
  // and whether anything ran from the text (window.pwned)
  Object.assign(annotations.report, { selected: a.id, title: panelTitle.textContent, text: panelText.textContent,
                                      scripts: document.scripts.length, pwned: window.pwned === undefined ? null : window.pwned });
  hash.set('annotation', a.id);
  annotations.pending = move ? a : null;
  if (camera && box)
    startMove();
  placeMarkers();
}

function deselect() {
  annotations.selected = -1;
  panel.style.display = 'none';
  Object.assign(annotations.report, { selected: null, title: null, text: null });
  hash.delete('annotation');
  placeMarkers();
}
panel.addEventListener('click', deselect);

// The camera of a stored view (share.js) and its light (null: the head
// light), which the page takes on arrival as meshview does, or null; its
// planes and points are left to the page's tools as they are.
function viewCamera(text) {
  const v = MsShare.parse(text);
  if (v.error)
    return null;
  const up = [0, 0, 0];
  up[v.axis] = 1;
  const f = forwardOf(upFrame(up), v.yaw, v.pitch);
  return { position: v.target.map((x, k) => x - v.distance * f[k]), target: v.target.slice(), up, fovy: v.fovy,
           light: v.light };
}

// The pending selection's move, once the page has a camera.
function startMove() {
  const a = annotations.pending;
  annotations.pending = null;
  if (!a)
    return;
  let to = a.view ? viewCamera(a.view) : null;
  if (!to) { // no view (or one the page cannot read): the orbit centre goes to the point
    const offset = camera.position.map((x, k) => x - camera.target[k]);
    to = { target: a.point.slice(), position: a.point.map((x, k) => x + offset[k]), up: camera.up, fovy: camera.fovy };
  }
  moveCamera(to);
}

// Over MOVE_MS (smoothstep), as meshview moves: the orbit centre and the field
// of view linearly, the distance geometrically, yaw the shorter way round and
// pitch about the view's up (another up than the camera's: there at once).
function moveCamera(to) {
  const from = orbitState(camera), end = orbitState(to);
  const fromTarget = camera.target.slice(), fromFovy = camera.fovy;
  const turn = Math.atan2(Math.sin(end.yaw - from.yaw), Math.cos(end.yaw - from.yaw));
  const jump = from.frame.axis !== end.frame.axis || from.frame.axis === undefined;
  const start = performance.now(), run = {};
  annotations.moving = run;
  let set = null;           // what the last step set: a drag or the wheel since stops the move
  const step = now => {
    if (annotations.moving !== run || (set && camera.position.some((x, k) => x !== set[k])))
      return;               // another selection, or the visitor, took over
    const t = jump ? 1 : Math.min(1, (now - start) / MOVE_MS), f = t * t * (3 - 2 * t);
    const st = { frame: end.frame, distance: from.distance * Math.pow(end.distance / from.distance, f),
                 yaw: from.yaw + f * turn, pitch: from.pitch + f * (end.pitch - from.pitch) };
    placeCamera(st, fromTarget.map((x, k) => x + f * (to.target[k] - x)));
    camera.fovy = fromFovy + f * (to.fovy - fromFovy);
    if (t === 1) {          // there exactly: the view's own camera, and its light
      camera.position = to.position.slice();
      camera.target = to.target.slice();
      camera.up = to.up.slice();
      if ('light' in to)
        MsTools.setLight(to.light);
    }
    set = camera.position.slice();
    cameraMoved();
    if (t < 1)
      requestAnimationFrame(step);
    else
      annotations.moving = null;
  };
  requestAnimationFrame(step);
}

// ---- view.js's hooks ----------------------------------------------------------

function annotationsOnMesh(positions, triangles) {
  annotations.mesh = { positions, triangles };
  scheduleOcclusion();
}

function annotationsOnDraw() {
  if (annotations.pending)
    startMove();
  placeMarkers();
  scheduleOcclusion();
}

loadAnnotations();
