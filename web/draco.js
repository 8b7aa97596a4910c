// The Draco page (/web/draco.html#model=NAME&cam=..., docs/BROWSER.md): the
// baseline the streaming viewer is measured against (issue 36). It downloads
// the model's whole Draco file, decodes it with Draco's own WebAssembly
// decoder (npm draco3d) in a Web Worker (draco-worker.js), so the page never
// stalls, uploads it and draws it once with WebGL 2:
//   #model=NAME                              the model (required)
//   &cam=PX,PY,PZ,TX,TY,TZ,UX,UY,UZ,FOVY     the viewer's camera (default: its home view)
//   &hud=0                                   no overlay (pictures for tests)
// A new #cam= in the hash redraws there. window.meshstream holds the page's
// state as the viewer's does, so tests/browser-page drives both: state
// ('loading', 'complete', 'error'), message, triangles, bytes (the Draco
// file's), firstPixelMs and completeMs (from navigation: the same moment
// here, the whole model drawn at once), timing (the worker's seconds).
//
// The draw path is a copy of web/view.js's (its camera text, view-projection,
// home camera, depth range and lit shader, less the tools: head light only,
// no section planes): view.js runs its viewer as it loads and leans on the
// tools (MsTools), so it cannot be loaded as a library, and moving its draw
// path into a shared file would rework the viewer's script. Keep the two
// shaders the same law (docs/BROWSER.md, "The page").
'use strict';

const TOKEN_KEY = 'meshstream-token';   // the viewer's: the token form keeps it
const page = { state: 'loading', message: '', triangles: 0, bytes: 0, firstPixelMs: null,
               completeMs: null, timing: null };
window.meshstream = page;

const canvas = document.getElementById('view');
const statusLine = document.getElementById('status');
const figures = document.getElementById('figures');

function say(text, isError) {
  statusLine.textContent = text;
  statusLine.className = isError ? 'error' : '';
  page.message = text;
}

function failPage(text) {
  say(text, true);
  page.state = 'error';
}

const hash = new URLSearchParams(location.hash.slice(1));
const name = hash.get('model') || '';
document.getElementById('model').textContent = name;
document.title = name + ' · Draco · meshstream';
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

let camera = parseCamera(hash.get('cam'));

// ---- The draw path: view.js's (see above) -----------------------------------

const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const norm = a => { const l = Math.hypot(...a); return [a[0] / l, a[1] / l, a[2] / l]; };

const viewProjection = MsCamera.viewProjection; // web/camera.js

const VERTEX = `#version 300 es
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
uniform mat4 viewProjection;
out vec3 world;
out vec3 smoothNormal;
void main() {
  world = position;
  smoothNormal = normal;
  gl_Position = viewProjection * vec4(position, 1.0);
}`;

// meshview's lit shading in its geometry mode with the head light
// (client/view/shaders/cell.frag.glsl, LIT, the viewer's default options),
// ported by hand: the viewer itself draws with that very shader
// (web/render.js, docs/BROWSER.md "Drawing").
const FRAGMENT = `#version 300 es
precision highp float;
in vec3 world;
in vec3 smoothNormal;
uniform vec3 eye;
out vec4 colour;
const vec3 ALBEDO = vec3(0.72, 0.69, 0.64);
const float SPECULAR = 0.18, SHININESS = 40.0;
vec3 srgbEncode(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}
void main() {
  vec3 g = cross(dFdx(world), dFdy(world));
  g = dot(g, g) > 0.0 ? normalize(g) : vec3(0.0, 0.0, 1.0);
  vec3 ng = gl_FrontFacing ? g : -g;
  vec3 n = ng;
  float len = length(smoothNormal);
  if (len > 1e-30)
    n = smoothNormal / len;
  if (dot(n, ng) < 0.0)
    n = ng;
  vec3 v = normalize(eye - world);
  if (dot(ng, v) < 0.0) {
    ng = -ng;
    n = -n;
  }
  vec3 l = v;
  float selfShadow = max(0.0, dot(l, n));
  float diffuse = selfShadow * max(0.0, dot(n, l));
  float highlight = selfShadow * pow(max(0.0, dot(n, normalize(l + v))), SHININESS);
  vec3 linear = ALBEDO * (0.05 + 0.95 * diffuse) + SPECULAR * highlight;
  colour = vec4(srgbEncode(linear), 1.0);
}`;

const BACKGROUND = 0.1517;   // meshview's: linear 0.02, sRGB-encoded

const gl = canvas.getContext('webgl2', { antialias: false });
let program = null, vao = null, indexCount = 0, box = null;

function compile(type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS))
    throw new Error('shader: ' + gl.getShaderInfoLog(s));
  return s;
}

function setUpGl() {
  program = gl.createProgram();
  gl.attachShader(program, compile(gl.VERTEX_SHADER, VERTEX));
  gl.attachShader(program, compile(gl.FRAGMENT_SHADER, FRAGMENT));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS))
    throw new Error('program: ' + gl.getProgramInfoLog(program));
  vao = gl.createVertexArray();
  gl.enable(gl.DEPTH_TEST);
}

function upload(positions, normals, triangles) {
  gl.bindVertexArray(vao);
  [positions, normals].forEach((data, location) => {
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(location);
    gl.vertexAttribPointer(location, 3, gl.FLOAT, false, 0, 0);
  });
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, triangles, gl.STATIC_DRAW);
  indexCount = triangles.length;
}

function resize() {
  const ratio = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * ratio));
  const h = Math.max(1, Math.round(canvas.clientHeight * ratio));
  if (canvas.width !== w || canvas.height !== h) {
    canvas.width = w;
    canvas.height = h;
  }
}

// Clipping planes that frame the model's box (origin, side) from the camera.
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

// The viewer's home view of the bounds (lo, hi).
function homeCamera(bounds) {
  const lo = bounds.slice(0, 3), hi = bounds.slice(3, 6);
  const fovy = 40, centre = [0, 1, 2].map(a => (lo[a] + hi[a]) / 2);
  const radius = Math.hypot(...sub(hi, lo)) / 2;
  const distance = 1.05 * radius / Math.sin(fovy * Math.PI / 360);
  const dir = norm([Math.sin(0.35), 0.25, Math.cos(0.35)]);
  return { position: centre.map((c, a) => c + distance * dir[a]), target: centre, up: [0, 1, 0], fovy };
}

function draw() {
  resize();
  gl.viewport(0, 0, canvas.width, canvas.height);
  gl.clearColor(BACKGROUND, BACKGROUND, BACKGROUND, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  if (!indexCount)
    return;
  const [near, far] = depthRange();
  gl.useProgram(program);
  gl.uniformMatrix4fv(gl.getUniformLocation(program, 'viewProjection'), false,
                      viewProjection(camera, canvas.width, canvas.height, near, far));
  gl.uniform3fv(gl.getUniformLocation(program, 'eye'), camera.position);
  gl.bindVertexArray(vao);
  gl.drawElements(gl.TRIANGLES, indexCount, gl.UNSIGNED_INT, 0);
  if (page.firstPixelMs === null)
    page.firstPixelMs = Math.round(performance.now());
}

window.addEventListener('resize', () => { if (indexCount) requestAnimationFrame(draw); });
window.addEventListener('hashchange', () => {
  const c = parseCamera(new URLSearchParams(location.hash.slice(1)).get('cam'));
  if (c && indexCount) {
    camera = c;
    requestAnimationFrame(draw);
  }
});

// ---- The worker ----------------------------------------------------------

function received(m) {
  // the model's box as the viewer's depth range wants it: origin and side
  const side = Math.max(m.bounds[3] - m.bounds[0], m.bounds[4] - m.bounds[1], m.bounds[5] - m.bounds[2]);
  box = [m.bounds[0], m.bounds[1], m.bounds[2], side > 0 ? side : 1];
  if (!camera)
    camera = homeCamera(m.bounds);
  upload(m.positions, m.normals, m.triangles);
  page.triangles = m.triangles.length / 3;
  page.bytes = m.bytes;
  page.timing = m.timing;
  requestAnimationFrame(() => {
    draw();
    page.completeMs = page.firstPixelMs;
    page.state = 'complete';
    say(name + ': ' + page.triangles.toLocaleString('en') + ' triangles, ' +
        (page.bytes / 1e3).toFixed(0) + ' kB of Draco, decoded whole');
    figures.textContent = 'first pixels ' + page.firstPixelMs + ' ms · download ' +
      m.timing.download.toFixed(2) + ' s · decode ' + m.timing.decode.toFixed(2) + ' s';
  });
}

function start() {
  if (!/^[A-Za-z0-9_.-]+$/.test(name)) {
    failPage('No model in the URL (#model=NAME).');
    return;
  }
  if (hash.get('cam') && !camera) {
    failPage('The camera in the URL is not ten numbers (#cam=PX,PY,PZ,TX,TY,TZ,UX,UY,UZ,FOVY).');
    return;
  }
  if (!gl) {
    failPage('This browser offers no WebGL 2: the model cannot be drawn.');
    return;
  }
  say('Loading ' + name + '\'s Draco file…');
  const worker = new Worker('draco-worker.js');
  worker.onerror = e => failPage('The decoder failed: ' + (e.message || 'the worker did not start'));
  worker.onmessage = e => {
    if (page.state === 'error')
      return;
    if (e.data.type === 'mesh')
      received(e.data);
    else
      failPage(e.data.message);
  };
  worker.postMessage({ name, token: sessionStorage.getItem(TOKEN_KEY) || '' });
  try {
    setUpGl();
  } catch (e) {
    worker.terminate();
    failPage('WebGL 2 failed: ' + e.message);
  }
}

start();
