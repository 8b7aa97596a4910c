// The page's tools for looking closely (docs/BROWSER.md, "Light",
// "Sections", "Measuring", "Help"): the state of light.js, section.js and
// measure.js, their keys, buttons and pointer input, their HUD lines, the
// worker's part (section planes, casts) and their place in meshview's view
// text (share.js) in the URL. Loaded before view.js; it reads view.js's
// camera, box, canvas and worker when an event comes, and view.js calls
// MsTools at a few points (the light and planes a frame draws with, the
// worker's messages, the URL).
'use strict';

const MsTools = (() => {
  const st = { light: null, sections: [], points: [], measuring: false, modelBits: 0, castSeq: 0,
               fromText: null, refineSeq: 0, refining: 0, unit: null };
  const el = id => document.getElementById(id);

  function sameCamera(a, b) {
    return a && b && a.fovy === b.fovy && [0, 1, 2].every(k => a.position[k] === b.position[k] &&
      a.target[k] === b.target[k] && a.up[k] === b.up[k]);
  }

  // ---- State into the page's figures, the HUD and the URL ----------------

  function publish() {
    const page = window.meshstream;
    page.light = st.light ? { az: st.light.az, el: st.light.el } : null;
    page.sections = st.sections.map(s => ({ point: s.point.slice(), normal: s.normal.slice() }));
    page.measuring = st.measuring;
    const r = MsMeasure.result(st.points, st.modelBits);
    page.measure = { points: st.points.map(p => p.hit ? Object.assign({ refined: !!p.refined }, p.hit) : null),
                     length: r ? r.length : null, precision: r ? r.precision : null,
                     bitsMin: r ? r.bitsMin : 0, full: r ? r.full : false, unit: st.unit || 'model units',
                     refining: st.refining > 0,
                     view: MsMeasure.result(st.points.map(p => ({ hit: p.viewHit || p.hit })), st.modelBits), refined: st.points.length > 0 && st.points.every(p => p.refined),
                     text: MsMeasure.describe(st.points, st.modelBits, st.unit) + (st.refining ? '  refining' : '') };
    const lines = [];
    if (st.light)
      lines.push(MsLight.describe(st.light));
    if (st.sections.length)
      lines.push(MsSection.describe(st.sections));
    if (st.measuring || st.points.length)
      lines.push(page.measure.text + (st.measuring ? '  [T]' : ''));
    const box = el('tool-lines');
    if (box)
      box.textContent = lines.join('\n');
  }

  // The view text of the camera and the tools' state, or null when the
  // camera's up is not a coordinate axis (meshview's text cannot say it).
  function viewText(c) {
    let orbit;
    if (st.fromText && sameCamera(c, st.fromText.camera)) {
      orbit = st.fromText.orbit;
    } else {
      const o = orbitState(c);
      if (o.frame.axis === undefined)
        return null;
      orbit = { target: c.target.slice(), distance: o.distance, yaw: o.yaw, pitch: o.pitch, fovy: c.fovy,
                axis: o.frame.axis };
    }
    return MsShare.print(Object.assign({}, orbit, {
      light: st.light, sections: st.sections,
      points: st.points.map(p => ({ anchor: p.hit ? p.hit.point : p.anchor, direction: p.direction })) }));
  }

  // The URL's hash: #cam= for a camera alone (with the head light, no
  // planes, no points), else meshview's #view= text.
  function toHash(hash) {
    const extras = st.light || st.sections.length || st.points.length;
    const text = extras && camera ? viewText(camera) : null;
    if (text) {
      hash.set('view', text);
      hash.delete('cam');
    } else {
      hash.set('cam', cameraText(camera));
      hash.delete('view');
    }
  }

  // The hash's text with the view text's commas, colons, slashes and equals
  // signs as they are (all safe in a fragment; '+' stays %2B).
  function hashString(h) {
    return h.toString().replace(/%2C/g, ',').replace(/%3A/g, ':').replace(/%2F/g, '/').replace(/%3D/g, '=');
  }

  function writeUrl() {
    if (!camera)
      return;
    toHash(hash);
    history.replaceState(null, '', '#' + hashString(hash));
    showShare();
  }

  // ---- A view text from the URL ------------------------------------------

  // The camera of a view text (and the tools' state from it), or null.
  function fromView(text) {
    const v = MsShare.parse(text);
    st.error = v.error || '';
    if (v.error)
      return null;
    const up = [0, 0, 0];
    up[v.axis] = 1;
    const f = forwardOf(upFrame(up), v.yaw, v.pitch);
    const c = { position: v.target.map((x, k) => x - v.distance * f[k]), target: v.target.slice(), up,
                fovy: v.fovy };
    st.fromText = { camera: { position: c.position.slice(), target: c.target.slice(), up: up.slice(), fovy: c.fovy },
                    orbit: v };
    st.light = v.light;
    st.sections = v.sections;
    st.points = v.points.map(p => ({ anchor: p.anchor, direction: p.direction, hit: null }));
    publish();
    if (worker && box) {        // a text typed into the URL: the planes, a new plan
      sendSections();
      worker.postMessage({ type: 'camera', camera: workerCamera() });
      recast();
      requestDraw();
    }
    return c;
  }

  // ---- The worker --------------------------------------------------------

  function sendSections() {
    if (worker)
      worker.postMessage({ type: 'sections', planes: MsSection.planes(st.sections) });
  }

  // Every point cast again from its anchor along its ray (the hit nearest it).
  function recast() {
    if (!worker || !st.points.length)
      return;
    worker.postMessage({ type: 'cast', seq: ++st.castSeq, rays: st.points.map(p => ({
      origin: p.hit ? p.hit.point : p.anchor, direction: p.direction, tMin: -Infinity, tNear: 0 })) });
  }

  // Once the view is complete, the points not refined yet go to the
  // worker's probe (full precision under each); one round at a time.
  function refineSoon() {
    const todo = st.points.filter(p => p.hit && !p.refined);
    if (st.refining || !todo.length || window.meshstream.state !== 'complete' || !worker)
      return;
    st.refining = todo.length;
    todo.forEach(p => { p.viewHit = p.hit; });     // as the view held it
    worker.postMessage({ type: 'refine', seq: ++st.refineSeq,
                         points: todo.map(p => ({ point: p.hit.point, direction: p.direction })) });
    st.refineList = todo;
  }

  // A worker message view.js does not know; true when it was the tools'.
  // The model's box also brings its unit (view.js handles the rest of it).
  function message(m) {
    if (m.type === 'box')
      st.unit = m.unit || null;
    if (m.type !== 'cast')
      return false;
    if (m.refine) {
      if (m.seq !== st.refineSeq)
        return true;                // a round the chain has dropped
      const p = st.refineList ? st.refineList[m.index] : null;
      st.refining = Math.max(0, st.refining - 1);
      if (p && st.points.includes(p)) {
        p.refined = true;           // the view's frames no longer move it
        if (m.hit) {
          p.hit = m.hit;
          p.anchor = m.hit.point;
        }
      }
    } else if (m.add) {
      if (m.hits[0] && st.points.length < MsMeasure.MAX) {
        st.modelBits = m.hits[0].modelBits;
        st.points.push({ anchor: m.hits[0].point, direction: m.direction, hit: m.hits[0] });
      }
    } else if (m.seq === st.castSeq) {
      m.hits.forEach((h, i) => {
        if (!st.points[i] || st.points[i].refined)
          return;
        st.points[i].hit = h;
        if (h) {
          st.points[i].anchor = h.point;
          st.modelBits = h.modelBits;
        }
      });
    }
    refineSoon();
    publish();
    writeUrl();
    requestDraw();
    return true;
  }

  function started() {
    sendSections();
    recast();
    publish();
  }

  // ---- Input -------------------------------------------------------------

  function changed(redrawOnly) {
    publish();
    requestDraw();
    writeUrl();
    if (!redrawOnly && camera && box) {
      sendSections();
      worker.postMessage({ type: 'camera', camera: workerCamera() });
      recast();
    }
  }

  // A light from elsewhere (an annotation's stored view): null is the head light.
  function setLight(light) {
    st.light = light ? { az: light.az, el: light.el } : null;
    changed(true);
  }

  function act(key) {
    if (!camera || !box)
      return false;
    if (key === 'l' || key === 'L') {
      st.light = MsLight.nextPreset(st.light);
      changed(true);
      return true;
    }
    const next = MsSection.key(st.sections, key, camera, box[3]);
    if (next) {
      st.sections = next;
      changed(false);
      return true;
    }
    if (key === 't' || key === 'T') {
      st.measuring = !st.measuring;
      changed(true);
      return true;
    }
    if (key === 'Backspace' || key === 'Delete') {
      if (key === 'Backspace')
        st.points.pop();
      else
        st.points = [];
      if (st.refining) {        // answers of the round under way are dropped
        st.refining = 0;
        st.refineSeq++;
      }
      changed(true);
      return true;
    }
    if (key === '?') {
      el('help').classList.toggle('hidden');
      return true;
    }
    return false;
  }

  window.addEventListener('keydown', e => {
    if (e.target instanceof HTMLInputElement || e.ctrlKey || e.metaKey || e.altKey)
      return;
    if (act(e.key))
      e.preventDefault();
  });

  const BUTTONS = { 'tool-light': 'l', 'tool-section': 'y', 'tool-flip': 'j', 'tool-back': '9',
                    'tool-forward': '0', 'tool-unsection': 'i', 'tool-measure': 't', 'tool-undo': 'Backspace',
                    'tool-help': '?' };
  for (const [id, key] of Object.entries(BUTTONS)) {
    const b = el(id);
    if (b)
      b.addEventListener('click', () => act(key));
  }
  const close = el('help-close');
  if (close)
    close.addEventListener('click', () => el('help').classList.add('hidden'));

  // Ctrl (or Alt) + drag moves the light; view.js never sees that drag. A
  // click while measuring adds a point. Registered before view.js's.
  const surface = el('view');
  let lightDrag = null, press = null;
  surface.addEventListener('pointerdown', e => {
    press = e.button === 0 ? [e.clientX, e.clientY] : null;
    if ((e.ctrlKey || e.altKey) && e.button === 0 && camera) {
      lightDrag = [e.clientX, e.clientY];
      surface.setPointerCapture(e.pointerId);
      e.stopImmediatePropagation();
    }
  });
  surface.addEventListener('pointermove', e => {
    if (!lightDrag)
      return;
    const ratio = window.devicePixelRatio || 1;
    st.light = MsLight.drag(st.light, (e.clientX - lightDrag[0]) * ratio, (e.clientY - lightDrag[1]) * ratio,
                            surface.height);
    lightDrag = [e.clientX, e.clientY];
    e.stopImmediatePropagation();
    changed(true);
  });
  surface.addEventListener('pointerup', e => {
    if (lightDrag) {
      lightDrag = null;
      press = null;
      e.stopImmediatePropagation();
      return;
    }
    if (st.measuring && press && camera && worker && Math.hypot(e.clientX - press[0], e.clientY - press[1]) < 3) {
      const ratio = window.devicePixelRatio || 1;
      const ray = MsMeasure.pixelRay(camera, e.clientX * ratio, e.clientY * ratio, surface.width, surface.height);
      worker.postMessage({ type: 'cast', add: true, direction: ray.direction,
                           rays: [{ origin: ray.origin, direction: ray.direction, tMin: 0, tNear: 0 }] });
    }
    press = null;
  });

  // ---- Drawing -----------------------------------------------------------

  // What a frame draws with (web/render.js): the light's direction in eye
  // space, towards it (null: the head light), the planes (a b c d, the side
  // a x + b y + c z + d > 0 cut away) and the section colour.
  function lighting() {
    return { light: st.light ? MsLight.eye(st.light) : null, planes: MsSection.planes(st.sections),
             sectionColour: MsSection.COLOUR };
  }

  function drawn(c) {
    MsMeasure.draw(st.points, c);
  }

  // For scripts and tests: the state's text and a measuring click at a
  // framebuffer point (what a click there does).
  function measureAt(x, y) {
    const ray = MsMeasure.pixelRay(camera, x, y, surface.width, surface.height);
    worker.postMessage({ type: 'cast', add: true, direction: ray.direction,
                         rays: [{ origin: ray.origin, direction: ray.direction, tMin: 0, tNear: 0 }] });
  }

  // A point by its ray (origin, direction in model units), as a click casts.
  function measureRay(origin, direction) {
    worker.postMessage({ type: 'cast', add: true, direction,
                         rays: [{ origin, direction, tMin: 0, tNear: 0 }] });
  }

  // Why the last view text was refused ('' when it was not).
  function viewError() {
    return st.error || '';
  }

  return { viewText, viewError, toHash, hashString, fromView, message, started, recast, lighting, drawn, act,
           measureAt, measureRay, publish, setLight };
})();
