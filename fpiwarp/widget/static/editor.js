// fpiwarp's editor in the browser: WebGL2 plumbing, overlays and input.
//
// This file holds no map and no sampler. The programs it compiles come
// from Python, assembled from the files in glsl/ (fpiwarp/widget/shaders.py:
// the desktop preview's fullscreen.vert + preview.frag in GLSL ES 3.00);
// the parameter block it uploads is transform.params() of the map's inverse,
// built in Python from the handles (fpiwarp/widget/session.py, with the
// desktop viewer's Editor). A drag sends the handle's position and draws
// the reply; moves are coalesced while one is in flight.
//
// createEditor(root, transport): transport.send(msg) posts a page message;
// transport.getImage() -> {meta, buffer} the display texture;
// transport.getProgram(key) -> {vertex, fragment}. The host calls
// editor.setState(state) with every state Python sends.

const TOGGLES = { h: "handles", o: "outline", c: "checkerboard", d: "heatmap" };
const ALL_OVERLAYS = ["handles", "outline", "checkerboard", "heatmap"];
const CLEAR = [0.12, 0.12, 0.14, 1.0];

function css(c) {
  return `rgba(${Math.round(c[0] * 255)}, ${Math.round(c[1] * 255)}, ${Math.round(c[2] * 255)}, ${c[3]})`;
}

function toBase64(bytes) {
  let s = "";
  for (let i = 0; i < bytes.length; i += 0x8000) {
    s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  }
  return btoa(s);
}

function fromBase64(text) {
  const s = atob(text);
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}

// The heat map legend's colours: the "jet" scale of preview_shade.glsl's
// pv_jet, evaluated for the legend's strip only (the frame's colours come
// from the shader).
function jet(t) {
  const f = (x) => Math.min(1, Math.max(0, 1.5 - Math.abs(4 * t - x)));
  return [f(3), f(2), f(1), 1];
}

// Pixels of 1..4 channels as RGBA for the texture (the desktop renderer's
// swizzles: gray RRR1, gray+alpha RRRG, RGB1, RGBA); integer values
// normalised like its textures (uint8 / 255 by the texture unit, uint16 /
// 65535 here, float as it is).
function rgbaTexels(meta, buffer) {
  const n = meta.width * meta.height;
  const c = meta.channels;
  let src;
  let out;
  let one;
  let scale = 1;
  if (meta.dtype === "uint8") {
    src = new Uint8Array(buffer);
    out = new Uint8Array(4 * n);
    one = 255;
  } else {
    src = meta.dtype === "uint16" ? new Uint16Array(buffer) : new Float32Array(buffer);
    scale = meta.dtype === "uint16" ? 1 / 65535 : 1;
    out = new Float32Array(4 * n);
    one = 1;
  }
  for (let i = 0; i < n; i++) {
    const s = i * c;
    const o = 4 * i;
    if (c <= 2) {
      const v = src[s] * scale;
      out[o] = out[o + 1] = out[o + 2] = v;
      out[o + 3] = c === 2 ? src[s + 1] * scale : one;
    } else {
      out[o] = src[s] * scale;
      out[o + 1] = src[s + 1] * scale;
      out[o + 2] = src[s + 2] * scale;
      out[o + 3] = c === 4 ? src[s + 3] * scale : one;
    }
  }
  return out;
}

export function createEditor(root, transport) {
  root.classList.add("fpw-editor");
  root.tabIndex = 0;
  root.innerHTML = `
    <div class="fpw-toolbar">
      <button data-key="h" title="H: handles">Handles</button>
      <button data-key="o" title="O: outline of the source quad's edges">Outline</button>
      <button data-key="c" title="C: checkerboard of the source">Checkerboard</button>
      <button data-key="d" title="D: distortion heat map">Heat map</button>
      <span class="fpw-sep"></span>
      <button data-key="f" title="F: fit the view to the warped content">Fit</button>
      <button data-key="a" title="A: antialiasing on/off (the view and the export)">Antialias</button>
      <button data-key="r" title="R: reset the points">Reset</button>
      <button data-key="x" title="X: free the constrained edges">Clear edges</button>
      <button data-key="s" title="S: save the spec (JSON)">Save spec</button>
      <button data-key="e" title="E: export the warped image at full resolution">Export</button>
    </div>
    <div class="fpw-stage">
      <canvas class="fpw-gl"></canvas>
      <canvas class="fpw-overlay"></canvas>
      <div class="fpw-legend" hidden>
        <canvas class="fpw-legend-bar" width="160" height="10"></canvas>
        <div class="fpw-legend-labels"><span class="fpw-lo"></span><span class="fpw-hi"></span></div>
      </div>
    </div>
    <div class="fpw-status" role="status"></div>`;
  const stage = root.querySelector(".fpw-stage");
  const glCanvas = root.querySelector(".fpw-gl");
  const ovCanvas = root.querySelector(".fpw-overlay");
  const legend = root.querySelector(".fpw-legend");
  const status = root.querySelector(".fpw-status");

  const ed = {
    state: null,
    overlays: new Set(),
    view: null, // [x0, y0, x1, y1] of output space shown
    fixedSize: null, // [w, h] canvas pixels while capturing
    drag: null, // {index, xy}
    pan: null,
    queue: [],
    sent: 0,
    acked: 0,
    frames: 0,
    compiled: [], // {key, vertex, fragment} as compiled, for tests
    failures: [],
    lastView: null,
    imageVersion: -1,
    tex: null,
    texFloat: false,
    texels: null,
    atlas: null,
    pyramidBuilds: 0, // atlases built (tests: one per picture)
  };

  const gl = glCanvas.getContext("webgl2", {
    antialias: false, alpha: false, premultipliedAlpha: false, preserveDrawingBuffer: true,
  });
  if (!gl) {
    status.textContent = "This browser has no WebGL2: the preview cannot be drawn.";
    ed.failures.push("no WebGL2");
    return ed;
  }
  const ubo = gl.createBuffer();
  const vao = gl.createVertexArray();
  const programs = new Map(); // key -> {program, uniforms, blockSize}
  let blockData = new Float32Array(0);
  let chain = Promise.resolve();
  const floatTargets = gl.getExtension("EXT_color_buffer_float") !== null;

  // ---- programs
  function compile(type, text) {
    const sh = gl.createShader(type);
    gl.shaderSource(sh, text);
    gl.compileShader(sh);
    if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) {
      throw new Error(`shader compile failed: ${gl.getShaderInfoLog(sh)}`);
    }
    return sh;
  }

  async function program(key) {
    let p = programs.get(key);
    if (p) return p;
    const src = await transport.getProgram(key);
    const prog = gl.createProgram();
    gl.attachShader(prog, compile(gl.VERTEX_SHADER, src.vertex));
    gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, src.fragment));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) {
      throw new Error(`program link failed: ${gl.getProgramInfoLog(prog)}`);
    }
    const index = gl.getUniformBlockIndex(prog, "FpiwarpParams");
    gl.uniformBlockBinding(prog, index, 0);
    const blockSize = gl.getActiveUniformBlockParameter(prog, index, gl.UNIFORM_BLOCK_DATA_SIZE);
    const uniforms = {};
    const count = gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < count; i++) {
      const info = gl.getActiveUniform(prog, i);
      uniforms[info.name] = { loc: gl.getUniformLocation(prog, info.name), type: info.type };
    }
    p = { program: prog, uniforms, blockSize };
    programs.set(key, p);
    ed.compiled.push({ key, vertex: src.vertex, fragment: src.fragment });
    return p;
  }

  function setUniform(p, name, value) {
    const u = p.uniforms[name];
    if (!u || u.loc === null) return; // dropped by the compiler
    const v = Array.isArray(value) ? value : [value];
    switch (u.type) {
      case gl.INT_VEC2: gl.uniform2i(u.loc, v[0], v[1]); break;
      case gl.INT: case gl.SAMPLER_2D: gl.uniform1i(u.loc, v[0]); break;
      case gl.FLOAT_VEC4: gl.uniform4fv(u.loc, v); break;
      case gl.FLOAT_VEC2: gl.uniform2fv(u.loc, v); break;
      default: gl.uniform1f(u.loc, v[0]);
    }
  }

  // ---- the image
  async function loadImage(version) {
    const { meta, buffer } = await transport.getImage();
    if (ed.tex) gl.deleteTexture(ed.tex);
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    const texels = rgbaTexels(meta, buffer);
    const isFloat = meta.dtype !== "uint8";
    gl.texImage2D(gl.TEXTURE_2D, 0, isFloat ? gl.RGBA32F : gl.RGBA8, meta.width, meta.height, 0, gl.RGBA,
      isFloat ? gl.FLOAT : gl.UNSIGNED_BYTE, texels);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST); // read texel by texel: no mipmaps
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    ed.tex = tex;
    ed.texFloat = isFloat;
    ed.texels = { data: texels, width: meta.width, height: meta.height, unit: isFloat ? 1 : 255 };
    if (ed.atlas) gl.deleteTexture(ed.atlas);
    ed.atlas = null; // the pyramid of this picture: built on the first antialiased frame
    ed.imageVersion = meta.version ?? version;
  }

  // ---- the pyramid of antialiasing (fpiwarp/sampling/pyramid.py, glsl/include/antialias.glsl): levels >= 1
  // of the display texture, each level's texel the mean of 2 x 2 texels of the one below (indices past the
  // last row or column clamped), in float64 as the reference, stored as float32 in one RGBA32F atlas at the
  // rectangles Python's fpiwarp.backends.gl.pyramid.atlas_layout gives (state.pyramid)
  function atlasTexels(t, pyramid) {
    const [aw, ah] = pyramid.size;
    const rects = pyramid.levels;
    const atlas = new Float32Array(4 * aw * ah);
    let level = Float64Array.from(t.data, (v) => v / t.unit);
    let lw = t.width;
    let lh = t.height;
    for (let k = 1; k < rects.length; k++) {
      const [x0, y0, nw, nh] = rects[k];
      const next = new Float64Array(4 * nw * nh);
      for (let i = 0; i < nh; i++) {
        const r0 = 4 * lw * (2 * i);
        const r1 = 4 * lw * Math.min(2 * i + 1, lh - 1);
        for (let j = 0; j < nw; j++) {
          const c0 = 4 * (2 * j);
          const c1 = 4 * Math.min(2 * j + 1, lw - 1);
          for (let ch = 0; ch < 4; ch++) {
            const v = 0.25 * ((level[r0 + c0 + ch] + level[r0 + c1 + ch]) + (level[r1 + c0 + ch] + level[r1 + c1 + ch]));
            next[4 * (i * nw + j) + ch] = v;
            atlas[4 * ((y0 + i) * aw + x0 + j) + ch] = v;
          }
        }
      }
      level = next;
      lw = nw;
      lh = nh;
    }
    return atlas;
  }

  function loadPyramid(pyramid) {
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, pyramid.size[0], pyramid.size[1], 0, gl.RGBA, gl.FLOAT,
      atlasTexels(ed.texels, pyramid));
    // float textures are complete only with NEAREST filters (the shader reads texels: no float filtering needed)
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    ed.atlas = tex;
    ed.pyramidBuilds += 1;
  }

  // ---- state from Python
  async function apply(state) {
    const first = ed.state === null;
    if (state.image.version !== ed.imageVersion) await loadImage(state.image.version);
    if (state.antialias && !ed.atlas) loadPyramid(state.pyramid);
    const p = await program(state.program);
    const rows = fromBase64(state.block);
    const size = Math.max(p.blockSize, rows.length);
    if (blockData.byteLength !== size) blockData = new Float32Array(size / 4);
    blockData.fill(0);
    blockData.set(new Float32Array(rows.buffer, 0, rows.length / 4));
    gl.bindBuffer(gl.UNIFORM_BUFFER, ubo);
    gl.bufferData(gl.UNIFORM_BUFFER, blockData, gl.DYNAMIC_DRAW);
    if (first) state.overlays.forEach((o) => ed.overlays.add(o));
    const viewKey = JSON.stringify(state.view);
    if (viewKey !== ed.lastView) { // Python framed the content (first view, F)
      ed.view = state.view.slice();
      ed.lastView = viewKey;
    }
    ed.state = state;
    ed.acked = Math.max(ed.acked, state.seq);
    if (ed.drag === null) ed.dragXY = null;
    draw();
    flush();
    settle();
  }

  // The next state is taken as a first one (overlays, view).
  ed.restart = () => {
    chain = chain.then(() => { ed.state = null; ed.overlays.clear(); ed.lastView = null; });
  };

  ed.setState = (state) => {
    chain = chain.then(() => apply(state)).catch((err) => fail(err));
    return chain;
  };

  function fail(err) {
    const text = String(err && err.message ? err.message : err);
    ed.failures.push(text);
    status.textContent = `error: ${text}`;
    console.error(`fpiwarp: ${text}`);
  }

  // ---- messages to Python (a drag's moves coalesce while one is in flight)
  function post(msg) {
    const last = ed.queue[ed.queue.length - 1];
    if (msg.type === "move" && last && last.type === "move" && last.index === msg.index) {
      ed.queue[ed.queue.length - 1] = msg;
    } else {
      ed.queue.push(msg);
    }
    flush();
  }

  function flush() {
    if (ed.sent > ed.acked || ed.queue.length === 0) return;
    const msg = ed.queue.shift();
    msg.seq = ++ed.sent;
    Promise.resolve(transport.send(msg)).catch((err) => {
      ed.acked = ed.sent;
      status.textContent = `error: ${err.message || err}`;
      flush();
      settle();
    });
  }
  ed.post = post;

  // Resolves once every message sent was answered and drawn.
  const waiters = [];
  function settle() {
    chain.then(() => {
      if (ed.state && ed.queue.length === 0 && ed.sent <= ed.acked) {
        waiters.splice(0).forEach((resolve) => resolve(ed.frames));
      }
    });
  }
  ed.whenIdle = () => new Promise((resolve) => {
    waiters.push(resolve);
    settle();
  });

  // Waits for the GPU (a one-pixel read): frame timing in benchmarks.
  ed.finish = () => {
    const px = new Uint8Array(4);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    return px[0];
  };
  // Draw the view at a fixed canvas size (null: follow the page).
  ed.setFixedSize = (size, view) => {
    ed.fixedSize = size;
    if (view) ed.view = view.slice();
    draw();
  };

  // ---- coordinates: output pixels <-> canvas pixels (GL's window, y up)
  function canvasSize() {
    if (ed.fixedSize) return ed.fixedSize;
    const dpr = window.devicePixelRatio || 1;
    const r = stage.getBoundingClientRect();
    return [Math.max(1, Math.round(r.width * dpr)), Math.max(1, Math.round(r.height * dpr))];
  }

  // fpw_view: output = view.xy + view.zw * (window - 0.5), the view's
  // rectangle fitted into the canvas, aspect kept, centred (as
  // fpiwarp.viewer.Renderer.view_params for a window, y up)
  function viewParams(w, h) {
    const [x0, y0, x1, y1] = ed.view;
    const s = Math.max((x1 - x0) / w, (y1 - y0) / h);
    const cx = 0.5 * (x0 + x1);
    const cy = 0.5 * (y0 + y1);
    return [cx + s * (0.5 - 0.5 * w), cy + s * (0.5 * h - 0.5), s, -s];
  }

  function toCanvas(pt, v, h) {
    // output point -> canvas pixel, y down from the top (2D canvas)
    return [(pt[0] - v[0]) / v[2] + 0.5, h - ((pt[1] - v[1]) / v[3] + 0.5)];
  }

  function toOutput(px, py) {
    const dpr = ed.fixedSize ? 1 : (window.devicePixelRatio || 1);
    const [w, h] = canvasSize();
    const v = viewParams(w, h);
    const wx = px * dpr;
    const wy = h - py * dpr;
    return [v[0] + v[2] * (wx - 0.5), v[1] + v[3] * (wy - 0.5)];
  }
  ed.toOutput = toOutput;
  ed.toScreen = (pt) => {
    const dpr = ed.fixedSize ? 1 : (window.devicePixelRatio || 1);
    const [w, h] = canvasSize();
    const c = toCanvas(pt, viewParams(w, h), h);
    return [c[0] / dpr, c[1] / dpr];
  };

  // ---- drawing
  function draw() {
    const st = ed.state;
    if (!st || !ed.tex) return;
    const [w, h] = canvasSize();
    for (const c of [glCanvas, ovCanvas]) {
      if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    }
    renderFrame(null, w, h);
    drawOverlay(w, h);
    ed.frames += 1;
  }
  ed.draw = draw;

  function renderFrame(target, w, h) {
    const st = ed.state;
    const p = programs.get(st.program);
    gl.bindFramebuffer(gl.FRAMEBUFFER, target);
    gl.viewport(0, 0, w, h);
    gl.disable(gl.BLEND);
    gl.clearColor(...CLEAR);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.useProgram(p.program);
    const u = st.uniforms;
    setUniform(p, "fpw_view", viewParams(w, h));
    setUniform(p, "fpw_src", 0);
    for (const name of ["fpw_src_size", "fpw_cval", "pv_background", "pv_checker_mix", "pv_heat_max",
      "pv_dilation"]) {
      setUniform(p, name, u[name]);
    }
    setUniform(p, "pv_checker", ed.overlays.has("checkerboard") ? st.checker_size : 0.0);
    setUniform(p, "pv_heat", ed.overlays.has("heatmap") ? st.heat_mix : 0.0);
    if (st.antialias) {
      const levels = new Int32Array(4 * (st.pyramid.max_level + 1));
      levels.set(st.pyramid.levels.flat());
      const loc = p.uniforms["fpw_levels[0]"];
      if (loc) gl.uniform4iv(loc.loc, levels);
      setUniform(p, "fpw_aa_top", st.pyramid.levels.length - 1);
      setUniform(p, "fpw_pyramid", 2);
      gl.activeTexture(gl.TEXTURE2);
      gl.bindTexture(gl.TEXTURE_2D, ed.atlas);
    }
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, ed.tex);
    gl.bindBufferBase(gl.UNIFORM_BUFFER, 0, ubo);
    gl.bindVertexArray(vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.bindVertexArray(null);
  }

  function drawOverlay(w, h, show = true) {
    const st = ed.state;
    const ctx = ovCanvas.getContext("2d");
    ctx.clearRect(0, 0, w, h);
    const heat = show && ed.overlays.has("heatmap");
    legend.hidden = !heat;
    if (heat) drawLegend();
    if (!show) return;
    const v = viewParams(w, h);
    const dpr = ed.fixedSize ? 1 : (window.devicePixelRatio || 1);
    const col = st.colors;
    // the export area: what E writes (the image's extent)
    const [ax0, ay0, ax1, ay1] = st.export_area;
    const a = toCanvas([ax0, ay0], v, h);
    const b = toCanvas([ax1, ay1], v, h);
    ctx.save();
    ctx.lineWidth = dpr;
    ctx.setLineDash([6 * dpr, 4 * dpr]);
    ctx.strokeStyle = "rgba(255, 255, 255, 0.8)";
    ctx.strokeRect(Math.min(a[0], b[0]), Math.min(a[1], b[1]), Math.abs(b[0] - a[0]), Math.abs(b[1] - a[1]));
    ctx.restore();
    if (ed.overlays.has("outline") && st.curves) {
      ctx.lineWidth = 2 * dpr;
      st.curves.forEach((curve, k) => {
        ctx.strokeStyle = css(st.edges.includes(k) ? col.constrained : col.edge);
        ctx.beginPath();
        let open = false;
        for (const pt of curve) {
          if (pt[0] === null || pt[1] === null) { open = false; continue; }
          const c = toCanvas(pt, v, h);
          if (open) ctx.lineTo(c[0], c[1]); else ctx.moveTo(c[0], c[1]);
          open = true;
        }
        ctx.stroke();
      });
    }
    if (ed.overlays.has("handles")) {
      const r = 6 * dpr;
      st.dst.forEach((pt, i) => {
        const xy = ed.drag && ed.drag.index === i && ed.dragXY ? ed.dragXY : pt;
        const c = toCanvas(xy, v, h);
        ctx.beginPath();
        ctx.arc(c[0], c[1], r + 1.5 * dpr, 0, 2 * Math.PI);
        ctx.fillStyle = css(col.ring);
        ctx.fill();
        ctx.beginPath();
        ctx.arc(c[0], c[1], r, 0, 2 * Math.PI);
        const active = st.invalid || (ed.drag && ed.drag.index === i);
        ctx.fillStyle = css(active ? col.active : col.handle);
        ctx.fill();
      });
    }
    status.textContent = st.title + (st.saved.length ? ` | wrote ${st.saved.join(", ")}` : "");
  }

  function drawLegend() {
    const bar = legend.querySelector(".fpw-legend-bar");
    const ctx = bar.getContext("2d");
    for (let x = 0; x < bar.width; x++) {
      ctx.fillStyle = css(jet(x / (bar.width - 1)));
      ctx.fillRect(x, 0, 1, bar.height);
    }
    const dmax = ed.state.uniforms.pv_heat_max;
    legend.querySelector(".fpw-lo").textContent = "K 1 (conformal)";
    legend.querySelector(".fpw-hi").textContent = `K ${((1 + dmax) / (1 - dmax)).toFixed(1)}+`;
  }

  // ---- capture (tests, screenshots): one frame of w x h canvas pixels
  // showing `view` (default the export area), read back top row first.
  // format "rgba8": the canvas as shown (with the overlays if asked);
  // "float": the same program into a float32 target (values before the
  // canvas' 8-bit rounding).
  ed.capture = (opts = {}) => {
    const st = ed.state;
    const w = opts.width ?? st.image.width;
    const h = opts.height ?? st.image.height;
    const saved = { view: ed.view, fixed: ed.fixedSize };
    ed.view = opts.view ?? st.export_area.slice();
    ed.fixedSize = [w, h];
    try {
      if (opts.format === "float") {
        if (!floatTargets) throw new Error("no EXT_color_buffer_float: float targets cannot be read");
        const tex = gl.createTexture();
        gl.bindTexture(gl.TEXTURE_2D, tex);
        gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, w, h);
        const fbo = gl.createFramebuffer();
        gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
        gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
        renderFrame(fbo, w, h);
        const px = new Float32Array(4 * w * h);
        gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, px);
        gl.bindFramebuffer(gl.FRAMEBUFFER, null);
        gl.deleteFramebuffer(fbo);
        gl.deleteTexture(tex);
        return { width: w, height: h, data: toBase64(flipRows(new Uint8Array(px.buffer), 16 * w, h)) };
      }
      for (const c of [glCanvas, ovCanvas]) { c.width = w; c.height = h; }
      renderFrame(null, w, h);
      drawOverlay(w, h, Boolean(opts.overlays));
      if (opts.overlays) {
        const out = document.createElement("canvas");
        out.width = w;
        out.height = h;
        const ctx = out.getContext("2d");
        ctx.drawImage(glCanvas, 0, 0);
        ctx.drawImage(ovCanvas, 0, 0);
        const data = ctx.getImageData(0, 0, w, h).data;
        return { width: w, height: h, data: toBase64(new Uint8Array(data.buffer)) };
      }
      const px = new Uint8Array(4 * w * h);
      gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
      return { width: w, height: h, data: toBase64(flipRows(px, 4 * w, h)) };
    } finally {
      ed.view = saved.view;
      ed.fixedSize = saved.fixed;
      draw();
    }
  };

  function flipRows(bytes, stride, h) {
    const out = new Uint8Array(bytes.length);
    for (let y = 0; y < h; y++) out.set(bytes.subarray((h - 1 - y) * stride, (h - y) * stride), y * stride);
    return out;
  }

  ed.info = () => ({
    renderer: gl.getParameter(gl.RENDERER),
    vendor: gl.getParameter(gl.VENDOR),
    version: gl.getParameter(gl.VERSION),
    glsl: gl.getParameter(gl.SHADING_LANGUAGE_VERSION),
    maxTexture: gl.getParameter(gl.MAX_TEXTURE_SIZE),
    floatTargets,
    unmasked: (() => {
      const ext = gl.getExtension("WEBGL_debug_renderer_info");
      return ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : null;
    })(),
  });

  // ---- input
  function pickHandle(px, py) {
    const st = ed.state;
    let best = -1;
    let dist = st.pick_radius;
    st.dst.forEach((pt, i) => {
      const [sx, sy] = ed.toScreen(pt);
      const d = Math.hypot(sx - px, sy - py);
      if (d <= dist) { dist = d; best = i; }
    });
    return best;
  }

  function pickEdge(px, py) {
    const st = ed.state;
    if (!st.curves) return -1;
    let best = -1;
    let dist = st.pick_radius;
    st.curves.forEach((curve, k) => {
      for (const pt of curve) {
        if (pt[0] === null || pt[1] === null) continue;
        const [sx, sy] = ed.toScreen(pt);
        const d = Math.hypot(sx - px, sy - py);
        if (d <= dist) { dist = d; best = k; }
      }
    });
    return best;
  }

  function local(ev) {
    const r = ovCanvas.getBoundingClientRect();
    return [ev.clientX - r.left, ev.clientY - r.top];
  }

  ovCanvas.addEventListener("pointerdown", (ev) => {
    if (!ed.state) return;
    root.focus({ preventScroll: true });
    const [px, py] = local(ev);
    ovCanvas.setPointerCapture(ev.pointerId);
    const i = ed.state.editable ? pickHandle(px, py) : -1;
    if (i >= 0) {
      ed.drag = { index: i };
      ed.dragXY = ed.state.dst[i].slice();
      draw();
      return;
    }
    const k = ed.state.editable ? pickEdge(px, py) : -1;
    if (k >= 0) {
      post({ type: "edge", index: k });
      return;
    }
    ed.pan = { px, py, view: ed.view.slice() };
  });

  ovCanvas.addEventListener("pointermove", (ev) => {
    if (!ed.state) return;
    const [px, py] = local(ev);
    if (ed.drag) {
      const xy = toOutput(px, py);
      ed.dragXY = xy;
      post({ type: "move", index: ed.drag.index, xy });
      drawOverlay(...canvasSize());
    } else if (ed.pan) {
      const a = toOutput(ed.pan.px, ed.pan.py);
      const b = toOutput(px, py);
      ed.view = ed.view.map((v, j) => v - (j % 2 === 0 ? b[0] - a[0] : b[1] - a[1]));
      ed.pan.px = px;
      ed.pan.py = py;
      draw();
    }
  });

  const endPointer = () => {
    if (ed.drag) post({ type: "release" });
    ed.drag = null;
    ed.pan = null;
  };
  ovCanvas.addEventListener("pointerup", endPointer);
  ovCanvas.addEventListener("pointercancel", endPointer);

  ovCanvas.addEventListener("wheel", (ev) => {
    if (!ed.state) return;
    ev.preventDefault();
    const [px, py] = local(ev);
    const c = toOutput(px, py);
    const f = Math.exp(0.0015 * ev.deltaY);
    ed.view = [c[0] + (ed.view[0] - c[0]) * f, c[1] + (ed.view[1] - c[1]) * f,
      c[0] + (ed.view[2] - c[0]) * f, c[1] + (ed.view[3] - c[1]) * f];
    draw();
  }, { passive: false });

  function key(name) {
    if (!ed.state) return;
    if (name in TOGGLES) {
      const o = TOGGLES[name];
      if (ed.overlays.has(o)) ed.overlays.delete(o); else ed.overlays.add(o);
      draw();
    } else if (name === "n") {
      const on = !ALL_OVERLAYS.some((o) => ed.overlays.has(o));
      ed.overlays.clear();
      if (on) { ed.overlays.add("handles"); ed.overlays.add("outline"); }
      draw();
    } else if (name === "f") {
      ed.lastView = null; // adopt the fit Python sends back, even if unchanged
      post({ type: "key", key: "f" });
    } else if ("rxsea".includes(name)) {
      post({ type: "key", key: name });
    }
  }
  ed.key = key;

  root.addEventListener("keydown", (ev) => {
    if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
    const name = ev.key.toLowerCase();
    if ("hocdnfrxsea".includes(name) && name.length === 1) {
      ev.preventDefault();
      key(name);
    }
  });
  root.querySelectorAll("button[data-key]").forEach((b) => {
    b.addEventListener("click", () => key(b.dataset.key));
  });

  if (typeof ResizeObserver !== "undefined") new ResizeObserver(() => draw()).observe(stage);
  post({ type: "texture_limit", value: gl.getParameter(gl.MAX_TEXTURE_SIZE) });
  window.fpiwarpEditor = ed;
  return ed;
}
