// The page's renderer (docs/BROWSER.md, "Drawing"): meshview's own shaders
// (client/view/shaders/cell.vert.glsl, cell.frag.glsl), in GLSL ES 3.00 as
// web/es_shaders.py makes them at build time (MsShaders, shaders.js), drawn
// cell by cell as meshview draws (client/view/ms_render_draw.c): per cell its
// modelview (the view times the cell's cube, in doubles), its number and its
// tint; per frame the projection, the view's rotation, the shading mode and
// meshview's default lighting (one head light of colour 1, or the page's
// directional light; specular 0.18, shininess 40, two-sided, albedo 0.72
// 0.69 0.64, or a colour model's vertex colours: docs/BROWSER.md, "Colour";
// smooth vertex normals). The modes are meshview's --shading geometry,
// normals and cells (ms_render.h's LIT, NORMALS and CELLS).
'use strict';

const MsRender = (() => {
  // meshview's --shading names and ms_render.h's numbers: apo and geometry
  // are both LIT, with and without the APO normals (meshview's default apo;
  // normals and cells use them too where a cell has its chunk)
  const MODES = { apo: 0, geometry: 0, normals: 1, cells: 2 };
  const usesApo = name => name !== 'geometry';
  const ALBEDO = [0.72, 0.69, 0.64], SPECULAR = 0.18, SHININESS = 40;
  // meshview's background: linear 0.02, sRGB-encoded (but for NORMALS:
  // ms_render_draw.c's clear_frame writes it as it is)
  const BACKGROUND = 0.02;

  function srgbEncode(c) {
    c = Math.min(1, Math.max(0, c));
    return c <= 0.0031308 ? 12.92 * c : 1.055 * Math.pow(c, 1 / 2.4) - 0.055;
  }

  // ms_render_draw.c's cell_tint: a light, distinct linear colour per cell
  // number (golden-ratio hue steps, then roughly to linear).
  function cellTint(cell) {
    const h = ((cell * 0.6180339887498949) % 1) * 6;
    const s = 0.55, v = 0.85, f = h - Math.floor(h);
    const p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    const out = [[v, t, p], [q, v, p], [p, v, t], [p, q, v], [t, p, v], [v, p, q]][Math.floor(h) % 6];
    return out.map(x => x * x);
  }

  // The program's text: the marker line after #version gets the defines and
  // the precision statements (and, for APO, apo.glsl), as meshview's
  // ms_render_program_source inserts its own after the first line.
  function source(text, defines, extra) {
    const head = defines.map(d => '#define ' + d).join('\n') +
      '\nprecision highp float;\nprecision highp int;\nprecision highp usampler2D;\n' + (extra || '');
    return text.replace(MsShaders.marker, head);
  }

  function compile(gl, type, text) {
    const s = gl.createShader(type);
    gl.shaderSource(s, text);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS))
      throw new Error('shader: ' + gl.getShaderInfoLog(s));
    return s;
  }

  const UNIFORMS = ['apo_words', 'apo_on', 'apo_base', 'apo_root_internal', 'apo_stop_depth', 'apo_nearest_rule',
                    'apo_filter', 'apo_footprint_scale', 'modelview', 'projection', 'cell_cube', 'shading', 'world_to_eye', 'cell_number', 'cell_tint',
                    'smooth_on', 'albedo', 'light_count', 'light_eye', 'light_colour', 'light_range',
                    'specular_strength', 'shininess', 'two_sided', 'section_count', 'section_colour',
                    'section_plane', 'vertex_colour'];

  // coloured: the variant that reads the vertices' colours (MS_VERTEX_COLOUR,
  // as meshview links it for a model with colour)
  function link(gl, fragmentDefines, apoText, coloured) {
    const program = gl.createProgram();
    const colour = coloured ? ['MS_VERTEX_COLOUR 1'] : [];
    fragmentDefines = fragmentDefines.concat(colour);
    gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, source(MsShaders.vertex, colour)));
    gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, source(MsShaders.fragment, fragmentDefines, apoText)));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS))
      throw new Error('program: ' + gl.getProgramInfoLog(program));
    const u = {};
    for (const name of UNIFORMS)
      u[name] = gl.getUniformLocation(program, name);
    return { program, u };
  }

  // programs by [APO detail][vertex colours], linked when first wanted
  let gl = null;
  const programs = [[null, null], [null, null]];
  const LIT_DEFINES = ['MS_EFFECT_SPECULAR', 'MS_EFFECT_TWO_SIDED', 'MS_SECTIONS'];
  function program(apo, coloured) {
    const i = apo ? 1 : 0, j = coloured ? 1 : 0;
    if (!programs[i][j])
      programs[i][j] = apo ? link(gl, LIT_DEFINES.concat(['MS_EFFECT_DETAIL_NORMALS']), MsShaders.apo, coloured)
                           : link(gl, LIT_DEFINES, null, coloured);
    return programs[i][j];
  }
  // The mesh drawn (current) and the one going up (next): each a vertex array
  // over its own position, normal and index buffers, with its runs.
  let current = null, next = null;
  const meshStats = { bytes: 0, frames: 0, meshes: 0, dropped: 0 };

  function setUp(context) {
    gl = context;
    // what meshview's viewer draws with: specular, two-sided, sections
    program(false, false);
  }

  function meshBuffers(m) {
    const b = { vao: gl.createVertexArray(), position: gl.createBuffer(), normal: gl.createBuffer(),
                index: gl.createBuffer(), m, runs: m.runs, sent: 0 };
    gl.bindVertexArray(b.vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, b.position);
    gl.bufferData(gl.ARRAY_BUFFER, m.positions.byteLength, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, b.normal);
    gl.bufferData(gl.ARRAY_BUFFER, m.normals.byteLength, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 0, 0);
    // a colour model's r g b a per vertex (sRGB as scanned), normalised
    // bytes at meshview's location 2
    b.colour = m.colours ? gl.createBuffer() : null;
    if (b.colour) {
      gl.bindBuffer(gl.ARRAY_BUFFER, b.colour);
      gl.bufferData(gl.ARRAY_BUFFER, m.colours.byteLength, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(2);
      gl.vertexAttribPointer(2, 4, gl.UNSIGNED_BYTE, true, 0, 0);
    }
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, b.index);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, m.triangles.byteLength, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    b.parts = [[gl.ARRAY_BUFFER, b.position, m.positions], [gl.ARRAY_BUFFER, b.normal, m.normals],
               [gl.ELEMENT_ARRAY_BUFFER, b.index, m.triangles]];
    if (b.colour)
      b.parts.push([gl.ARRAY_BUFFER, b.colour, m.colours]);
    b.total = b.parts.reduce((sum, part) => sum + part[2].byteLength, 0);
    return b;
  }

  function dropBuffers(b) {
    if (!b)
      return;
    gl.deleteVertexArray(b.vao);
    gl.deleteBuffer(b.position);
    gl.deleteBuffer(b.normal);
    gl.deleteBuffer(b.index);
    if (b.colour)
      gl.deleteBuffer(b.colour);
  }

  // ---- APO texels: a 2D integer texture (WebGL 2 has no buffer textures) --
  // Words of every cell's chunk prefix in one R32UI texture ROW words wide
  // (the shader's MS_APO_ROW_BITS), word i at (i % ROW, i / ROW); a CPU copy
  // of them (mirror) allocated front to back. As meshview's renderer
  // (ms_render.c, ms_render_upload): a chunk's words go up within the frame's
  // upload budget (meshview's --upload-budget default, 4,000,000 bytes), over
  // several frames when more waits, and a cell draws with its new prefix only
  // once all of it is up (until then with the one before, or without).
  const ROW = 2048, UPLOAD_BUDGET = 4000000;
  let texture = null, mirror = new Uint32Array(0), used = 0;
  const chunks = new Map();     // cell: {current: {start, levels, root} or null, next: pending or null}
  const queue = [];             // cells with a pending chunk, in arrival order
  // texel bytes uploaded, frames that uploaded some, chunks made current,
  // textures made afresh (repacks: their whole upload, outside the budget, is
  // in bytes too), and per cell the levels of its latest chunk prefix
  // (window.meshstream.apo)
  const apoStats = { bytes: 0, frames: 0, chunks: 0, repacks: 0, levels: {} };

  function makeTexture(rows) {
    if (texture)
      gl.deleteTexture(texture);
    texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.R32UI, ROW, rows);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.bindTexture(gl.TEXTURE_2D, null);
  }

  // Words [from, to) of the mirror into the texture (whole rows where it can).
  function sendWords(from, to) {
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    while (from < to) {
      const row = Math.floor(from / ROW), x = from % ROW;
      let width, height;
      if (x > 0 || to - from < ROW) {
        width = Math.min(ROW - x, to - from);
        height = 1;
      } else {
        width = ROW;
        height = Math.floor((to - from) / ROW);
      }
      gl.texSubImage2D(gl.TEXTURE_2D, 0, x, row, width, height, gl.RED_INTEGER, gl.UNSIGNED_INT,
                       mirror.subarray(from, from + width * height));
      from += width * height;
    }
    gl.bindTexture(gl.TEXTURE_2D, null);
  }

  // Room for `count` more words: the live ones (current and pending) packed
  // into a texture with room to spare, sent again whole (outside the budget).
  function room(count) {
    if (used + count <= mirror.length)
      return;
    let live = count;
    for (const c of chunks.values())
      live += (c.current ? c.current.count : 0) + (c.next ? c.next.count : 0);
    const rows = Math.max(16, Math.ceil(2 * live / ROW));
    const packed = new Uint32Array(rows * ROW);
    let at = 0;
    for (const c of chunks.values())
      for (const part of [c.current, c.next])
        if (part) {
          packed.set(mirror.subarray(part.start, part.start + part.count), at);
          part.start = at;
          at += part.count;
        }
    mirror = packed;
    used = at;
    makeTexture(rows);
    sendWords(0, used);
    apoStats.bytes += 4 * used;
    apoStats.repacks++;
    for (const c of chunks.values())
      if (c.next)
        c.next.sent = c.next.count;
  }

  // A chunk prefix of the worker's: words of levels 0 .. levels - 1, and the
  // root's words (2: internal).
  function apoChunk(m) {
    room(m.words.length);
    const start = used;
    mirror.set(m.words, start);
    used += m.words.length;
    const c = chunks.get(m.cell) || { current: null, next: null };
    if (!c.next)
      queue.push(m.cell);
    c.next = { start, count: m.words.length, levels: m.levels, root: m.rootWords === 2, sent: 0 };
    chunks.set(m.cell, c);
    apoStats.levels[m.cell] = m.levels;
  }

  // The frame's share of the pending chunks, within `left` bytes; true while
  // some wait.
  function uploadApo(left) {
    const budget = left;
    while (queue.length && left > 0) {
      const c = chunks.get(queue[0]), p = c.next;
      const part = Math.min(p.count - p.sent, Math.floor(left / 4));
      if (part > 0) {
        sendWords(p.start + p.sent, p.start + p.sent + part);
        p.sent += part;
        left -= 4 * part;
        apoStats.bytes += 4 * part;
      }
      if (p.sent < p.count)
        break;
      c.current = p;
      c.next = null;
      apoStats.chunks++;
      queue.shift();
    }
    if (left < budget)
      apoStats.frames++;
    return queue.length > 0;
  }

  // A mesh of the worker's (positions and normals in world units, the
  // triangles, and runs: the cells and their triangles' ranges and cubes).
  // It goes up within the frames' upload budget (uploadMesh) into buffers of
  // its own, and replaces the mesh drawn once all of it is up; a newer mesh
  // replaces one still going up.
  function upload(m) {
    if (next) {
      dropBuffers(next);
      meshStats.dropped++;
    }
    next = meshBuffers(m);
  }

  // Up to `left` bytes of the next mesh; returns what it sent.
  function uploadMesh(left) {
    if (!next)
      return 0;
    let sent = 0, at = 0;
    gl.bindVertexArray(null);
    for (const [target, buffer, data] of next.parts) {
      const end = at + data.byteLength;
      if (next.sent < end && left > 0) {
        const from = next.sent - at, part = Math.min(data.byteLength - from, left);
        gl.bindBuffer(target, buffer);
        gl.bufferSubData(target, from, new Uint8Array(data.buffer, data.byteOffset + from, part));
        next.sent += part;
        left -= part;
        sent += part;
      }
      at = end;
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, null);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, null);
    meshStats.bytes += sent;
    if (next.sent === next.total) {
      dropBuffers(current);
      current = next;
      current.parts = null;      // the arrays are the GPU's now
      current.m = null;
      next = null;
      meshStats.meshes++;
    }
    return sent;
  }

  // The background of a mode, as the clear colour's grey.
  function background(mode) {
    return mode === MODES.normals ? BACKGROUND : srgbEncode(BACKGROUND);
  }

  // Column-major view (world to eye) and projection, in doubles.
  const matrices = MsCamera.matrices; // web/camera.js


  // ms_render_cell_modelview: view * [side I | origin], in doubles.
  function cellModelview(view, cube, out) {
    for (let col = 0; col < 3; ++col)
      for (let row = 0; row < 4; ++row)
        out[4 * col + row] = view[4 * col + row] * cube[3];
    for (let row = 0; row < 4; ++row)
      out[12 + row] = view[row] * cube[0] + view[4 + row] * cube[1] + view[8 + row] * cube[2] + view[12 + row];
  }

  // One frame. f: camera, width, height, near, far, mode (MODES), shading
  // (its name: whether APO normals are drawn), light (null:
  // the head light; else the light's direction in eye space, towards it),
  // planes (a b c d, the side a x + b y + c z + d > 0 cut away, world) and
  // sectionColour. Returns the cells drawn and whether APO texels wait for
  // the next frames' budget.
  function draw(f) {
    const grey = background(f.mode);
    gl.viewport(0, 0, f.width, f.height);
    gl.clearColor(grey, grey, grey, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    // meshview's order (ms_render_upload): the mesh, then the APO texels,
    // within one budget a frame
    const meshSent = uploadMesh(UPLOAD_BUDGET);
    if (meshSent)
      meshStats.frames++;
    const waiting = uploadApo(UPLOAD_BUDGET - meshSent) || next !== null;
    const runs = current ? current.runs : null, n = runs ? runs.cells.length : 0;
    if (!n || !f.camera)
      return { cells: 0, waiting };
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.disable(gl.CULL_FACE);
    gl.disable(gl.BLEND);
    const apo = usesApo(f.shading) && [...chunks.values()].some(c => c.current);
    const coloured = current.colour !== null;
    const p = program(apo, coloured), u = p.u;
    const { view, proj } = matrices(f.camera, f.width, f.height, f.near, f.far);
    gl.useProgram(p.program);
    gl.uniformMatrix4fv(u.projection, false, new Float32Array(proj));
    gl.uniformMatrix3fv(u.world_to_eye, false,
                        new Float32Array([view[0], view[1], view[2], view[4], view[5], view[6], view[8], view[9], view[10]]));
    gl.uniform1i(u.shading, f.mode);
    gl.uniform1i(u.smooth_on, 1);
    gl.uniform3fv(u.albedo, ALBEDO);
    if (coloured)
      gl.uniform1i(u.vertex_colour, 1);
    const eye = new Float32Array(32), colour = new Float32Array(24), range = new Float32Array(8);
    if (f.light) {
      const l = f.light, len = Math.hypot(...l);
      eye.set([l[0] / len, l[1] / len, l[2] / len, 0]);
    } else {
      eye.set([0, 0, 0, 2]);
    }
    colour.set([1, 1, 1]);
    range[0] = 1;
    gl.uniform1i(u.light_count, 1);
    gl.uniform4fv(u.light_eye, eye);
    gl.uniform3fv(u.light_colour, colour);
    gl.uniform1fv(u.light_range, range);
    gl.uniform1f(u.specular_strength, SPECULAR);
    gl.uniform1f(u.shininess, SHININESS);
    gl.uniform1i(u.two_sided, 1);
    const planes = f.planes || [];
    gl.uniform1i(u.section_count, planes.length);
    gl.uniform3fv(u.section_colour, f.sectionColour || [0, 0, 0]);
    if (apo) {
      // meshview's defaults (ms_render.c): a missing child gives no
      // correction, 8-cell filtering, no deeper than the pixel's footprint
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.uniform1i(u.apo_words, 0);
      gl.uniform1i(u.apo_nearest_rule, 0);
      gl.uniform1i(u.apo_filter, 1);
    }
    const footprint = 2 * Math.tan(f.camera.fovy * Math.PI / 360) / f.height;
    gl.bindVertexArray(current.vao);
    const modelview = new Float64Array(16), local = new Float32Array(12);
    for (let k = 0; k < n; ++k) {
      const first = runs.firsts[k], count = runs.firsts[k + 1] - first;
      if (!count)
        continue;
      const cube = runs.cubes.subarray(4 * k, 4 * k + 4), cell = runs.cells[k];
      cellModelview(view, cube, modelview);
      gl.uniformMatrix4fv(u.modelview, false, new Float32Array(modelview));
      gl.uniform4f(u.cell_cube, cube[0], cube[1], cube[2], cube[3]);
      gl.uniform1ui(u.cell_number, cell);
      gl.uniform3fv(u.cell_tint, cellTint(cell));
      // ms_render_draw.c's set_cell_sections: the kept side in the cell's frame
      local.fill(0);
      planes.forEach((s, j) => {
        for (let a = 0; a < 3; ++a)
          local[4 * j + a] = -s[a] * cube[3];
        local[4 * j + 3] = -(s[0] * cube[0] + s[1] * cube[1] + s[2] * cube[2] + s[3]);
      });
      gl.uniform4fv(u.section_plane, local);
      if (apo) {
        const c = chunks.get(cell), on = !!(c && c.current);
        gl.uniform1i(u.apo_on, on ? 1 : 0);
        if (on) {
          gl.uniform1i(u.apo_base, c.current.start);
          gl.uniform1i(u.apo_root_internal, c.current.root ? 1 : 0);
          gl.uniform1ui(u.apo_stop_depth, c.current.levels - 1);
          gl.uniform1f(u.apo_footprint_scale, footprint / cube[3]);   // ms_render_apo_footprint_scale
        }
      }
      gl.drawElements(gl.TRIANGLES, 3 * count, gl.UNSIGNED_INT, 12 * first);
    }
    gl.bindVertexArray(null);
    gl.bindTexture(gl.TEXTURE_2D, null);
    return { cells: n, waiting };
  }

  // Whether the next mesh or APO texels still wait for upload budget.
  const pending = () => next !== null || queue.length > 0;

  return { MODES, usesApo, setUp, upload, pending, apoChunk, apoStats, meshStats, draw, background, cellTint };
})();
