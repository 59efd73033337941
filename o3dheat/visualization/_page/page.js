/* o3dheat page viewer (o3dheat/visualization/_page/page.js; written by o3dheat.visualization.page).
 * Reads the JSON block #o3dheat-meta and the gzip+base64 blob #o3dheat-data of this page and draws
 * them with three.js (the global THREE, inlined above). Nothing is fetched.
 * Scripting API: window.o3dheat (see the "Scripting" block of the page and page.py's docstring);
 * setScale, setField and the other setters are synchronous: they update and redraw before returning.
 * Debugging: o3dheat.deferred (true when recolouring uses the deferred pass below),
 * o3dheat.setDeferred(on) (false: always draw the plain way; true: draws the G-buffer now; returns the
 * state in use) and o3dheat.timing.path ("deferred" or "plain": how the last frame was drawn).
 */
(function () {
  "use strict";
  const $ = (id) => document.getElementById(id);
  const KINDS = ["minima", "saddles", "maxima"], KIND = ["minimum", "saddle", "maximum"];
  const KIND_HEX = ["#1f4fe0", "#129a2c", "#d42020"]; // minima blue, saddles green, maxima red
  const FOV = 30; // vertical field of view, degrees
  const CB_WIDTH = 110; // pixels of the view under the colorbar
  const state = { field: 0, scale: 0, global: true, levels: false, markers: true, tracks: true, life: -Infinity };
  const api = (window.o3dheat = { ready: false, error: null, frames: 0, timing: {} });
  let meta, data, n, cur, renderer, scene, camera, canvas, mesh, geom, col32, positions, normals;
  let levelLines, trackTubes, markerMeshes = [], markerShapes, pickMarker, readout = { vertex: -1, pinned: false };
  const lut32 = new Uint32Array(256), table = new Uint32Array(65536);
  const view = { target: null, elev: 20, azim: -60, dist: 1 };
  const fieldCache = [];

  // ------------------------------------------------------------------ loading
  async function inflate(text) {
    let bytes;
    if (typeof Uint8Array.fromBase64 === "function") bytes = Uint8Array.fromBase64(text);
    else {
      const s = atob(text);
      bytes = new Uint8Array(s.length);
      for (let i = 0; i < s.length; i++) bytes[i] = s.charCodeAt(i);
    }
    if (typeof DecompressionStream !== "function")
      throw new Error("this browser cannot inflate the page's data (no DecompressionStream): use a recent " +
                      "Chrome, Edge, Firefox or Safari");
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
    return new Response(stream).arrayBuffer();
  }

  function fail(e) {
    api.error = String((e && e.message) || e);
    const box = $("o3h-message");
    box.className = "error";
    box.textContent = "The page cannot draw the surface: " + api.error;
    if (window.console) console.error(e);
  }

  async function start() {
    meta = JSON.parse($("o3dheat-meta").textContent);
    n = meta.n;
    describe();
    const buf = await inflate($("o3dheat-data").textContent.trim());
    api.timing.data = performance.now();
    data = (key) => { const [off, len, type] = meta.layout[key]; return new window[type](buf, off, len); };
    if (typeof THREE === "undefined") throw new Error("three.js did not load");
    for (let k = 0; k < 256; k++)
      lut32[k] = (meta.lut[3 * k] | (meta.lut[3 * k + 1] << 8) | (meta.lut[3 * k + 2] << 16) | 0xff000000) >>> 0;
    setUp();
    state.levels = meta.levels > 0;
    $("o3h-levels").checked = state.levels;
    $("o3h-levels").disabled = meta.levels === 0;
    $("o3h-nlevels").textContent = meta.levels;
    bindUI();
    bindControls();
    resize();
    resetView(false);
    selectField(0);
    draw();
    api.timing.firstFrame = performance.now();
    $("o3h-message").textContent = "";
    requestAnimationFrame(() => { api.ready = true; }); // the first frame has reached the screen
  }

  // ------------------------------------------------------------------ the three.js scene
  const VERTEX = `
    varying vec3 vNormal; varying vec3 vColor;
    uniform vec3 uColor;
    void main() {
      vec4 p = vec4(position, 1.0); vec3 nrm = normal;
      #ifdef USE_INSTANCING
        p = instanceMatrix * p; nrm = mat3(instanceMatrix) * nrm;
      #endif
      #if defined(USE_COLOR_ALPHA)
        vColor = color.rgb;
      #elif defined(USE_COLOR)
        vColor = color;
      #else
        vColor = uColor;
      #endif
      vNormal = normalMatrix * nrm;
      gl_Position = projectionMatrix * modelViewMatrix * p;
    }`;
  // Lambert shading by a light above and left of the viewer (as o3dheat's static pictures); both
  // sides lit, so open meshes show their inside.
  const FRAGMENT = `
    varying vec3 vNormal; varying vec3 vColor;
    uniform vec3 uLight; uniform float uAmbient;
    void main() {
      vec3 nrm = normalize(vNormal);
      if (!gl_FrontFacing) nrm = -nrm;
      float d = max(dot(nrm, uLight), 0.0);
      gl_FragColor = vec4(vColor * (uAmbient + (1.0 - uAmbient) * d), 1.0);
    }`;

  // True when WebGL is drawn by the CPU (SwiftShader, llvmpipe): a probe context's renderer string.
  function softwareGL() {
    const gl = document.createElement("canvas").getContext("webgl2");
    if (!gl) return false;
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
    const lose = gl.getExtension("WEBGL_lose_context");
    if (lose) lose.loseContext();
    return /swiftshader|llvmpipe|softpipe|software/i.test(name);
  }

  function shaded(options) {
    return new THREE.ShaderMaterial(Object.assign({
      vertexShader: VERTEX, fragmentShader: FRAGMENT, side: THREE.FrontSide,
      uniforms: { uColor: { value: new THREE.Color(0.6, 0.6, 0.6) },
                  uLight: { value: new THREE.Vector3(-0.35, 0.55, 1.0).normalize() }, uAmbient: { value: 0.38 } },
    }, options));
  }

  function setUp() {
    THREE.ColorManagement.enabled = false; // the LUT's sRGB bytes are shown as they are
    canvas = $("o3h-canvas");
    api.software = softwareGL();
    try { // no multisampling on a software rasterizer: it doubles the time of a frame there
      renderer = new THREE.WebGLRenderer({ canvas, antialias: !api.software });
    } catch (e) {
      throw new Error("WebGL 2 is not available in this browser (" + ((e && e.message) || e) + ")");
    }
    renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    renderer.setClearColor(0xffffff, 1);
    scene = new THREE.Scene();
    camera = new THREE.PerspectiveCamera(FOV, 1, 0.01, 100);
    camera.up.set(0, 0, 1);

    positions = data("positions");
    geom = new THREE.BufferGeometry();
    geom.setAttribute("position", new THREE.BufferAttribute(positions, 3));
    geom.setIndex(new THREE.BufferAttribute(data("faces"), 1));
    geom.computeVertexNormals();
    normals = geom.getAttribute("normal").array;
    // the vertex colours (RGBA bytes), padded to whole rows of the deferred pass's colour texture
    const colors = new Uint8Array(4 * TEX_W * Math.ceil(n / TEX_W));
    col32 = new Uint32Array(colors.buffer);
    const attr = new THREE.BufferAttribute(colors.subarray(0, 4 * n), 4, true);
    attr.setUsage(THREE.DynamicDrawUsage);
    geom.setAttribute("color", attr);
    geom.computeBoundingSphere();
    // both sides of an open surface are seen; a closed one (outward faces) shows only its front faces
    mesh = new THREE.Mesh(geom, shaded({ vertexColors: true, polygonOffset: true, polygonOffsetFactor: 1,
                                         polygonOffsetUnits: 1, side: meta.closed ? THREE.FrontSide
                                                                                  : THREE.DoubleSide }));
    scene.add(mesh);

    levelLines = lines(new THREE.LineBasicMaterial({ color: 0x1a1a1a }));
    trackTubes = new THREE.Mesh(new THREE.BufferGeometry(), shaded({ vertexColors: true }));
    trackTubes.frustumCulled = false;
    scene.add(trackTubes);

    // markers: one instanced sphere per kind, as many instances as the most at any scale of any field
    const sphere = new THREE.IcosahedronGeometry(1, 1); // 80 triangles; 8 when thousands are shown
    markerShapes = [sphere, new THREE.OctahedronGeometry(1, 0)];
    for (let k = 0; k < 3; k++) {
      let most = 1;
      for (const f of meta.fields) for (const c of f.counts) most = Math.max(most, c[k]);
      const m = new THREE.InstancedMesh(sphere, shaded({}), most);
      m.material.uniforms.uColor.value = new THREE.Color(KIND_HEX[k]);
      m.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
      m.frustumCulled = false;
      m.count = 0;
      markerMeshes.push(m);
      scene.add(m);
    }
    pickMarker = new THREE.Mesh(sphere, shaded({}));
    pickMarker.material.uniforms.uColor.value = new THREE.Color(0.08, 0.08, 0.08);
    pickMarker.visible = false;
    scene.add(pickMarker);

    // the deferred pass: where float colour buffers can be drawn to; on by default for a software
    // rasterizer (no multisampling there; a GPU draws the plain way, antialiased, in a few ms) and a
    // surface of DEFERRED_FACES faces or more (below, redrawing them costs less than the full-screen pass)
    const gl = renderer.getContext(), maxTex = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    deferred.able = renderer.extensions.has("EXT_color_buffer_float") && meta.m < 1 << 24 &&
      Math.ceil(Math.max(n, meta.m) / TEX_W) <= maxTex;
    deferred.on = deferred.able && api.software && meta.m >= DEFERRED_FACES;
    // its geometry lives on the GPU only: after a lost context, the page draws the plain way
    canvas.addEventListener("webglcontextlost", () => { deferred.able = deferred.on = deferred.valid = false; });
  }

  function lines(material) {
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3), 3));
    g.setDrawRange(0, 0);
    const l = new THREE.LineSegments(g, material);
    l.frustumCulled = false;
    scene.add(l);
    return l;
  }

  // Sets the first `count` vertices of a LineSegments' attribute `name` from `array` (grown as needed).
  function setLine(obj, name, array, count, itemSize) {
    let a = obj.geometry.getAttribute(name);
    if (a.array.length < count * itemSize) {
      const g = new THREE.BufferGeometry(); // a bigger buffer: a new geometry (the old one is freed)
      for (const [key, old] of Object.entries(obj.geometry.attributes))
        g.setAttribute(key, key === name ? new THREE.BufferAttribute(new Float32Array(array.length), itemSize)
                                         : old);
      obj.geometry.dispose();
      obj.geometry = g;
      a = g.getAttribute(name);
    }
    a.array.set(array.subarray(0, count * itemSize));
    a.clearUpdateRanges();
    a.addUpdateRange(0, Math.max(count * itemSize, 1));
    a.needsUpdate = true;
    obj.geometry.setDrawRange(0, count);
  }

  // 0.75% of the diagonal, smaller where the markers would cover more than about 9% of the surface
  function markerRadius() {
    const off = cur.meta.offsets, j = state.scale, count = Math.max(1, off[3 * j + 3] - off[3 * j]);
    return Math.min(0.0075 * meta.diagonal, 0.3 * Math.sqrt(meta.area / (Math.PI * count)));
  }

  // ------------------------------------------------------------------ fields and scales
  // the quantized values, stored per scale as two byte planes (high bytes, then low bytes): one Uint16Array
  function joined(planes, T) {
    const q = new Uint16Array(n * T);
    for (let j = 0; j < T; j++) {
      const hi = 2 * j * n, lo = hi + n, o = j * n;
      for (let v = 0; v < n; v++) q[o + v] = (planes[hi + v] << 8) | planes[lo + v];
    }
    return q;
  }

  function fieldData(i) {
    if (!fieldCache[i]) {
      const f = meta.fields[i];
      const c = { meta: f, q: joined(data(f.values), f.T), critical: data(f.critical), tracks: null };
      if (f.tracks) {
        const t = f.tracks;
        c.tracks = { p: t.p, vertex: data(t.vertex), kind: data(t.kind), lifetime: data(t.lifetime) };
        const finite = Array.from(c.tracks.lifetime).filter((x) => Number.isFinite(x));
        c.tracks.steps = Array.from(new Set(finite)).sort((a, b) => a - b);
      }
      fieldCache[i] = c;
    }
    return fieldCache[i];
  }

  function selectField(i) {
    state.field = i;
    cur = fieldData(i);
    const f = cur.meta;
    $("o3h-field").value = String(i);
    $("o3h-field-one").textContent = meta.fields.length > 1 ? "" : f.name;
    $("o3h-cb-title").textContent = f.name;
    $("o3h-cb-title").title = f.name;
    const slider = $("o3h-scale");
    slider.max = String(f.T - 1);
    state.scale = Math.min(state.scale, f.T - 1);
    const tr = cur.tracks;
    $("o3h-track-box").style.display = tr ? "" : "none";
    if (tr) syncLifeSlider();
    buildTracks();
    applyScale(state.scale);
  }

  function applyScale(j) {
    state.scale = j;
    $("o3h-scale").value = String(j);
    updateColors();
    updateLevels();
    updateMarkers();
    updateText();
    updateColorbar();
    updateReadout();
  }

  function range() {
    const f = cur.meta, j = state.scale;
    let a = state.global ? f.min : f.lo[j], b = state.global ? f.max : f.hi[j];
    if (!(b > a)) { const d = Math.abs(a) > 0 ? Math.abs(a) * 1e-6 : 1e-6; a -= d; b += d; }
    return [a, b];
  }

  function levelValues() {
    const [a, b] = range(), L = meta.levels, out = [];
    for (let k = 1; k <= L; k++) out.push(a + (k * (b - a)) / (L + 1)); // interior, evenly spaced
    return out;
  }

  function scaleValues() { return cur.q.subarray(state.scale * n, (state.scale + 1) * n); }

  function updateColors() {
    const f = cur.meta, j = state.scale, lo = f.lo[j], step = (f.hi[j] - lo) / 65535;
    const [a, b] = range(), k = 256 / (b - a);
    for (let q = 0; q < 65536; q++) {
      const c = Math.floor((lo + q * step - a) * k);
      table[q] = lut32[c < 0 ? 0 : c > 255 ? 255 : c];
    }
    const qs = scaleValues();
    for (let i = 0; i < n; i++) col32[i] = table[qs[i]];
    geom.getAttribute("color").needsUpdate = true; // uploaded when next drawn the plain way
    if (deferred.colors) deferred.colors.needsUpdate = true; // ... or the deferred way
  }

  let levelBuffer = new Float32Array(3 * 4096);
  function updateLevels() {
    levelLines.visible = state.levels && meta.levels > 0;
    if (!levelLines.visible) return;
    const f = cur.meta, j = state.scale, lo = f.lo[j], step = (f.hi[j] - lo) / 65535;
    if (!(step > 0)) { levelLines.geometry.setDrawRange(0, 0); return; }
    // marching triangles on the quantized values: level k at q = q0 + k dq; a vertex at the level is above it
    const [a, b] = range(), L = meta.levels;
    const q0 = (a - lo) / step, dq = (b - a) / (L + 1) / step;
    const qs = scaleValues(), F = geom.index.array, P = positions, m = F.length / 3;
    let out = levelBuffer, c = 0;
    for (let t = 0; t < m; t++) {
      const i0 = F[3 * t], i1 = F[3 * t + 1], i2 = F[3 * t + 2];
      const v0 = qs[i0], v1 = qs[i1], v2 = qs[i2];
      const lo3 = Math.min(v0, v1, v2), hi3 = Math.max(v0, v1, v2);
      let k = Math.max(1, Math.floor((lo3 - q0) / dq) + 1);
      const kEnd = Math.min(L, Math.floor((hi3 - q0) / dq));
      for (; k <= kEnd; k++) {
        const ql = q0 + k * dq;
        if (c + 6 > out.length) { const o = new Float32Array(out.length * 2); o.set(out); out = levelBuffer = o; }
        let e = 0;
        const s0 = v0 >= ql, s1 = v1 >= ql, s2 = v2 >= ql;
        if (s0 !== s1) { c = cut(out, c, P, i0, i1, v0, v1, ql); e++; }
        if (s1 !== s2) { c = cut(out, c, P, i1, i2, v1, v2, ql); e++; }
        if (s2 !== s0) { c = cut(out, c, P, i2, i0, v2, v0, ql); e++; }
        if (e !== 2) c -= 3 * e; // no crossing (rounding at the ends of the range)
      }
    }
    setLine(levelLines, "position", out, c / 3, 3);
  }

  function cut(out, c, P, i, j, vi, vj, ql) {
    const s = (ql - vi) / (vj - vi);
    out[c] = P[3 * i] + s * (P[3 * j] - P[3 * i]);
    out[c + 1] = P[3 * i + 1] + s * (P[3 * j + 1] - P[3 * i + 1]);
    out[c + 2] = P[3 * i + 2] + s * (P[3 * j + 2] - P[3 * i + 2]);
    return c + 3;
  }

  function updateMarkers() {
    const off = cur.meta.offsets, j = state.scale, r = markerRadius();
    const shape = markerShapes[off[3 * j + 3] - off[3 * j] > 3000 ? 1 : 0];
    for (let k = 0; k < 3; k++) {
      const mm = markerMeshes[k], a = off[3 * j + k], b = off[3 * j + k + 1], M = mm.instanceMatrix.array;
      mm.visible = state.markers;
      mm.geometry = shape;
      mm.count = b - a;
      for (let s = a; s < b; s++) {
        const v = cur.critical[s], o = 16 * (s - a);
        M.fill(0, o, o + 16);
        M[o] = M[o + 5] = M[o + 10] = r;
        M[o + 12] = positions[3 * v]; M[o + 13] = positions[3 * v + 1]; M[o + 14] = positions[3 * v + 2];
        M[o + 15] = 1;
      }
      mm.instanceMatrix.clearUpdateRanges();
      mm.instanceMatrix.addUpdateRange(0, Math.max(16 * (b - a), 1));
      mm.instanceMatrix.needsUpdate = true;
    }
  }

  // The tracks' paths through their vertices across the scales: thin tubes (six sides) resting on the
  // surface, in the colour of their kind.
  function buildTracks() {
    const tr = cur.tracks;
    trackTubes.visible = !!tr && state.tracks;
    if (!tr) return;
    const T = cur.meta.T, V = tr.vertex, r = 0.0016 * meta.diagonal, SIDES = 6;
    const at = (v) => new THREE.Vector3(positions[3 * v] + r * normals[3 * v], positions[3 * v + 1] +
                                        r * normals[3 * v + 1], positions[3 * v + 2] + r * normals[3 * v + 2]);
    const segments = [];
    for (let p = 0; p < tr.p; p++) {
      if (tr.lifetime[p] < state.life) continue; // NaN and infinite lifetimes are always kept
      for (let j = 0; j + 1 < T; j++) {
        const u = V[p * T + j], w = V[p * T + j + 1];
        if (u < 0 || w < 0 || u === w) continue;
        const a = at(u), b = at(w);
        if (a.distanceTo(b) <= meta.jump) segments.push([a, b, tr.kind[p]]); // longer: it would cut across the surface
      }
    }
    const nv = 2 * SIDES * segments.length, P = new Float32Array(3 * nv), N = new Float32Array(3 * nv);
    const C = new Float32Array(3 * nv), I = new Uint32Array(6 * SIDES * segments.length);
    const rgb = KIND_HEX.map((h) => new THREE.Color(h)), d = new THREE.Vector3(), u = new THREE.Vector3();
    const w = new THREE.Vector3(), o = new THREE.Vector3();
    segments.forEach(([a, b, kind], k) => {
      d.subVectors(b, a).normalize();
      const ax = Math.abs(d.x), ay = Math.abs(d.y), az = Math.abs(d.z); // the axis least along d
      u.set(ax <= ay && ax <= az ? 1 : 0, ay < ax && ay <= az ? 1 : 0, az < ax && az < ay ? 1 : 0);
      u.crossVectors(d, u).normalize();
      w.crossVectors(d, u);
      for (let s = 0; s < SIDES; s++) {
        const angle = (2 * Math.PI * s) / SIDES, v0 = 2 * SIDES * k + s, v1 = v0 + SIDES;
        o.copy(u).multiplyScalar(Math.cos(angle)).addScaledVector(w, Math.sin(angle));
        for (const [v, end] of [[v0, a], [v1, b]]) {
          P[3 * v] = end.x + r * o.x; P[3 * v + 1] = end.y + r * o.y; P[3 * v + 2] = end.z + r * o.z;
          N[3 * v] = o.x; N[3 * v + 1] = o.y; N[3 * v + 2] = o.z;
          C[3 * v] = rgb[kind].r; C[3 * v + 1] = rgb[kind].g; C[3 * v + 2] = rgb[kind].b;
        }
        const v2 = 2 * SIDES * k + ((s + 1) % SIDES), v3 = v2 + SIDES, t = 6 * (SIDES * k + s);
        I.set([v0, v2, v1, v2, v3, v1], t);
      }
    });
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(P, 3));
    g.setAttribute("normal", new THREE.BufferAttribute(N, 3));
    g.setAttribute("color", new THREE.BufferAttribute(C, 3));
    g.setIndex(new THREE.BufferAttribute(I, 1));
    trackTubes.geometry.dispose();
    trackTubes.geometry = g;
  }

  // The lifetime slider: 0 shows every track, k the tracks living at least the k-th smallest finite
  // lifetime, the last position only those alive at the last scale (lifetime ∞). state.life snaps to it.
  function syncLifeSlider() {
    const steps = cur.tracks.steps, L = steps.length;
    let k = 0;
    if (state.life > -Infinity) { k = steps.findIndex((x) => x >= state.life) + 1; if (k === 0) k = L + 1; }
    state.life = k === 0 ? -Infinity : k <= L ? steps[k - 1] : Infinity;
    $("o3h-life").max = String(L + 1);
    $("o3h-life").value = String(k);
    $("o3h-life-value").textContent = k === 0 ? "0 (all tracks)" : k <= L ? fmt(steps[k - 1])
                                                                     : "∞ (alive at the last scale)";
  }

  // ------------------------------------------------------------------ text
  function fmt(x, p = 4) {
    if (x === null || x === undefined || Number.isNaN(x)) return "–";
    if (!Number.isFinite(x)) return x > 0 ? "∞" : "−∞";
    if (x === 0) return "0";
    const a = Math.abs(x);
    const s = a >= 1e-3 && a < 1e5 ? String(Number(x.toPrecision(p))) : x.toExponential(p - 1).replace(/\.?0+e/, "e");
    return s.replace(/-/g, "−");
  }

  function describe() {
    $("o3h-name").textContent = meta.name;
    $("o3h-size").textContent = `${meta.n.toLocaleString("en")} vertices · ${meta.m.toLocaleString("en")} faces`;
    const labels = $("o3h-labels");
    for (const f of meta.fields) {
      const li = document.createElement("li"), b = document.createElement("b");
      b.textContent = f.name;
      li.append(b, f.label ? ": " + f.label : "", ` (${f.T} scale${f.T > 1 ? "s" : ""})`);
      labels.append(li);
    }
    const notes = $("o3h-notes");
    for (const s of meta.notes.length ? meta.notes : ["no notes on repairs or decimation"]) {
      const li = document.createElement("li");
      li.textContent = s;
      notes.append(li);
    }
    const select = $("o3h-field");
    meta.fields.forEach((f, i) => select.append(new Option(f.name, String(i))));
    select.style.display = meta.fields.length > 1 ? "" : "none";
  }

  function updateText() {
    const f = cur.meta, j = state.scale, t = f.times[j];
    $("o3h-t").textContent = (t === null ? `column ${j + 1} (time unknown)` : `t = ${fmt(t)}`) +
      ` · scale ${j + 1} of ${f.T}`;
    const eps = f.eps_inf ? f.eps_inf[j] : null;
    $("o3h-eps").textContent = f.eps_inf ? `ε∞ = ‖Φt f − f‖∞ / ‖f‖∞ = ${fmt(eps)}` : "";
    const box = $("o3h-counts");
    box.textContent = "";
    f.counts[j].forEach((c, k) => {
      const span = document.createElement("span"), dot = document.createElement("i");
      dot.className = "dot";
      dot.style.background = KIND_HEX[k];
      span.append(dot, `${c} ${c === 1 ? KIND[k] : KINDS[k]}`);
      box.append(span);
    });
    const hidden = f.hidden ? f.hidden[j] : 0;
    if (hidden > 0) {  // critical points of rounding errors on parts where the field is constant
      const span = document.createElement("span");
      span.className = "o3h-hidden";
      span.textContent = `(${hidden} on parts where the field is constant to rounding: not drawn)`;
      box.append(span);
    }
  }

  function updateColorbar() {
    const cb = $("o3h-cb-canvas");
    if (cb.dataset.cmap !== "1") { // the colormap, top = high
      const ctx = cb.getContext("2d"), img = ctx.createImageData(1, 256);
      for (let k = 0; k < 256; k++) {
        const o = 4 * (255 - k);
        img.data[o] = meta.lut[3 * k]; img.data[o + 1] = meta.lut[3 * k + 1];
        img.data[o + 2] = meta.lut[3 * k + 2]; img.data[o + 3] = 255;
      }
      ctx.putImageData(img, 0, 0);
      cb.dataset.cmap = "1";
    }
    const body = $("o3h-cb-body");
    body.querySelectorAll(".tick, .tick-mark, .lvl").forEach((e) => e.remove());
    const [a, b] = range();
    for (let k = 0; k <= 4; k++) {
      const d = document.createElement("div");
      d.className = "tick";
      d.style.top = `${100 - 25 * k}%`;
      d.textContent = fmt(a + ((b - a) * k) / 4, 3);
      const mark = document.createElement("div");
      mark.className = "tick-mark";
      mark.style.top = d.style.top;
      body.append(d, mark);
    }
    if (levelLines.visible)
      for (const v of levelValues()) {
        const d = document.createElement("div");
        d.className = "lvl";
        d.style.top = `${100 * (1 - (v - a) / (b - a))}%`;
        body.append(d);
      }
    $("o3h-cb-range").textContent = state.global ? "range: all scales" : "range: this scale";
  }

  function updateReadout() {
    const v = readout.vertex, box = $("o3h-readout");
    pickMarker.visible = v >= 0;
    if (v < 0) { box.textContent = ""; return; }
    const f = cur.meta, j = state.scale, q = scaleValues()[v];
    const value = f.lo[j] + (q * (f.hi[j] - f.lo[j])) / 65535;
    box.textContent = `vertex ${v} · ${f.name} = ${fmt(value, 5)}${readout.pinned ? "  (pinned: click to release)" : ""}`;
    pickMarker.position.set(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
    pickMarker.scale.setScalar(0.6 * markerRadius());
  }

  // ------------------------------------------------------------------ deferred recolouring
  // A software rasterizer (SwiftShader) takes 85-170 ms to draw 400k triangles, too slow to redraw the
  // surface at each scale change. While the camera rests, the surface is drawn once into an offscreen
  // G-buffer: per pixel (RGBA32F) the triangle's index, two barycentric coordinates (perspective-correct,
  // as the rasterizer interpolates the plain path's vertex colours) and the shading factor (0: no
  // surface), and the depth. A recolouring then draws only a full-screen pass: it reads the triangle's
  // three vertices (a texture of the faces) and their colours (a texture of the n vertex colours, made
  // by the same LUT as the plain path's colour attribute), interpolates, shades and writes the
  // G-buffer's depth, and the overlays (level sets, markers, tracks, the picked vertex) are drawn over it
  // as in the plain path, hidden where the surface is in front. Moving the camera or resizing draws the
  // plain way (so does a recolouring until the G-buffer is redrawn) and redraws the G-buffer once the
  // camera has rested for GBUFFER_DELAY ms.
  const TEX_W = 2048, TEX_SHIFT = 11; // the width of the data textures (vertex colours, faces)
  const GBUFFER_DELAY = 200;
  // SwiftShader on 2 cores: the full-screen pass ~17 ms at 1200 x 800; the plain way ~6 ms at 9k faces,
  // ~20 ms at 40k, ~115 ms at 400k
  const DEFERRED_FACES = 100000;
  const deferred = { able: false, on: false, valid: false, timer: 0, gScene: null, target: null,
                     cScene: null, cCamera: null, quad: null, colors: null, faces: null, compiled: false };
  const G_VERTEX = `
    varying vec3 vNormal; varying vec2 vBary; flat varying float vTri;
    void main() { // not indexed: corner k of triangle t is vertex 3 t + k
      int t = gl_VertexID / 3, k = gl_VertexID - 3 * t;
      vTri = float(t);
      vBary = vec2(k == 1 ? 1.0 : 0.0, k == 2 ? 1.0 : 0.0);
      vNormal = normalMatrix * normal;
      gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
    }`;
  const G_FRAGMENT = `
    varying vec3 vNormal; varying vec2 vBary; flat varying float vTri;
    uniform vec3 uLight; uniform float uAmbient;
    void main() { // the shading factor exactly as FRAGMENT computes it
      vec3 nrm = normalize(vNormal);
      if (!gl_FrontFacing) nrm = -nrm;
      float d = max(dot(nrm, uLight), 0.0);
      gl_FragColor = vec4(vTri, vBary, uAmbient + (1.0 - uAmbient) * d);
    }`;
  const C_VERTEX = `void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }`;
  const C_FRAGMENT = `
    uniform highp sampler2D uG, uDepth, uColors; uniform highp usampler2D uFaces;
    vec3 color(uint v) { return texelFetch(uColors, ivec2(int(v & ${TEX_W - 1}u), int(v >> ${TEX_SHIFT}u)), 0).rgb; }
    void main() {
      ivec2 p = ivec2(gl_FragCoord.xy);
      vec4 g = texelFetch(uG, p, 0);
      if (g.a == 0.0) discard; // the background (cleared)
      int t = int(g.r);
      uvec3 f = texelFetch(uFaces, ivec2(t & ${TEX_W - 1}, t >> ${TEX_SHIFT}), 0).xyz;
      vec3 c = (1.0 - g.g - g.b) * color(f.x) + g.g * color(f.y) + g.b * color(f.z);
      gl_FragColor = vec4(c * g.a, 1.0);
      gl_FragDepth = texelFetch(uDepth, p, 0).r;
    }`;

  // The deferred pass's geometry, textures and scenes (made once, at the first G-buffer).
  function deferredSetUp() {
    const F = geom.index.array, m = meta.m, P = new Float32Array(9 * m), N = new Float32Array(9 * m);
    for (let c = 0; c < 3 * m; c++) {
      const v = 3 * F[c], o = 3 * c;
      P[o] = positions[v]; P[o + 1] = positions[v + 1]; P[o + 2] = positions[v + 2];
      N[o] = normals[v]; N[o + 1] = normals[v + 1]; N[o + 2] = normals[v + 2];
    }
    const g = new THREE.BufferGeometry(), drop = function () { this.array = null; }; // kept on the GPU only
    g.setAttribute("position", new THREE.BufferAttribute(P, 3).onUpload(drop));
    g.setAttribute("normal", new THREE.BufferAttribute(N, 3).onUpload(drop));
    g.boundingSphere = geom.boundingSphere.clone(); // the same points (three sorts by it: not from P)
    const gm = new THREE.Mesh(g, shaded({ vertexShader: G_VERTEX, fragmentShader: G_FRAGMENT,
                                          polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
                                          side: mesh.material.side }));
    gm.frustumCulled = false;
    deferred.gScene = new THREE.Scene().add(gm);

    const texture = (array, rows, format, type, internal) => {
      const t = new THREE.DataTexture(array, TEX_W, rows, format, type);
      t.internalFormat = internal;
      t.minFilter = t.magFilter = THREE.NearestFilter;
      t.generateMipmaps = false;
      t.needsUpdate = true;
      return t;
    };
    deferred.colors = texture(new Uint8Array(col32.buffer), col32.length / TEX_W, THREE.RGBAFormat,
                              THREE.UnsignedByteType, "RGBA8");
    const rows = Math.ceil(m / TEX_W), faces = new Uint32Array(4 * TEX_W * rows);
    for (let t = 0; t < m; t++) {
      faces[4 * t] = F[3 * t]; faces[4 * t + 1] = F[3 * t + 1]; faces[4 * t + 2] = F[3 * t + 2];
    }
    deferred.faces = texture(faces, rows, THREE.RGBAIntegerFormat, THREE.UnsignedIntType, "RGBA32UI");
    const quad = new THREE.Mesh(new THREE.PlaneGeometry(2, 2), new THREE.ShaderMaterial({
      vertexShader: C_VERTEX, fragmentShader: C_FRAGMENT, depthTest: true, depthWrite: true,
      depthFunc: THREE.AlwaysDepth,
      uniforms: { uG: { value: null }, uDepth: { value: null }, uColors: { value: deferred.colors },
                  uFaces: { value: deferred.faces } },
    }));
    quad.frustumCulled = false;
    deferred.cScene = new THREE.Scene().add(quad);
    deferred.cCamera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);
    deferred.quad = quad;
  }

  // Draws the G-buffer for the current view when it is out of date; false when it cannot be drawn.
  const bufferSize = new THREE.Vector2();
  function gbuffer() {
    if (deferred.valid) return true;
    clearTimeout(deferred.timer);
    if (!deferred.gScene) deferredSetUp();
    const { x: w, y: h } = renderer.getDrawingBufferSize(bufferSize);
    let target = deferred.target;
    if (!target || target.width !== w || target.height !== h) {
      if (target) { target.depthTexture.dispose(); target.dispose(); }
      target = deferred.target = new THREE.WebGLRenderTarget(w, h, {
        type: THREE.FloatType, format: THREE.RGBAFormat, minFilter: THREE.NearestFilter,
        magFilter: THREE.NearestFilter, generateMipmaps: false,
        depthTexture: new THREE.DepthTexture(w, h, THREE.UnsignedIntType) }); // 24 bits, as the canvas's
      deferred.quad.material.uniforms.uG.value = target.texture;
      deferred.quad.material.uniforms.uDepth.value = target.depthTexture;
      renderer.setRenderTarget(target);
      const gl = renderer.getContext();
      if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) { // cannot draw to floats
        renderer.setRenderTarget(null);
        deferred.able = deferred.on = false;
        return false;
      }
    }
    renderer.setRenderTarget(target);
    renderer.setClearColor(0x000000, 0);
    renderer.render(deferred.gScene, camera);
    renderer.setRenderTarget(null);
    renderer.setClearColor(0xffffff, 1);
    deferred.valid = true;
    return true;
  }

  function composite() {
    renderer.render(deferred.cScene, deferred.cCamera); // clears to white, then the surface
    renderer.autoClear = false;
    mesh.visible = false; // the overlays, over the surface's depth
    try { renderer.render(scene, camera); } finally { mesh.visible = true; renderer.autoClear = true; }
  }

  // the camera or the size changed: the G-buffer is out of date; redraw it once the camera rests
  function viewChanged() {
    deferred.valid = false;
    if (!deferred.on) return;
    clearTimeout(deferred.timer);
    deferred.timer = setTimeout(() => {
      if (!(deferred.on && cur && gbuffer())) return;
      if (!deferred.compiled) { // the full-screen pass's program and textures, ready for the first recolouring
        renderer.compile(deferred.cScene, deferred.cCamera);
        renderer.initTexture(deferred.colors);
        renderer.initTexture(deferred.faces);
        deferred.compiled = true;
      }
      renderer.getContext().flush(); // hand the G-buffer to the GPU now (else it waits for the next frame)
    }, GBUFFER_DELAY);
  }

  // ------------------------------------------------------------------ drawing and the view
  // build: draw the G-buffer now if it is out of date (else the plain way until it is redrawn)
  function draw(build = false) {
    if (deferred.on && (deferred.valid || build) && gbuffer()) {
      composite();
      api.timing.path = "deferred";
    } else {
      renderer.render(scene, camera);
      api.timing.path = "plain";
    }
    api.frames++;
  }
  let pending = false;
  function requestDraw() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => { pending = false; draw(); });
  }

  function resize() {
    const box = $("o3h-view"), w = Math.max(box.clientWidth, 1), h = Math.max(box.clientHeight, 1);
    renderer.setSize(w, h, false);
    viewChanged();
    // the colorbar covers the right: the picture's centre moves left by half its width
    const shift = w > 3 * CB_WIDTH ? CB_WIDTH : 0;
    camera.aspect = (w + shift) / h;
    camera.setViewOffset(w + shift, h, shift, 0, w, h);
    if (view.target) placeCamera();
  }

  function axes() { // toward the eye, right, up (z up), for view.elev and view.azim
    const e = (view.elev * Math.PI) / 180, a = (view.azim * Math.PI) / 180;
    const d = new THREE.Vector3(Math.cos(e) * Math.cos(a), Math.cos(e) * Math.sin(a), Math.sin(e));
    const right = new THREE.Vector3(-Math.sin(a), Math.cos(a), 0);
    return [d, right, new THREE.Vector3().crossVectors(d, right)];
  }

  function placeCamera() {
    const [d] = axes();
    camera.position.copy(view.target).addScaledVector(d, view.dist);
    camera.lookAt(view.target);
    const far = camera.position.length() + 2 * meta.radius;
    camera.near = Math.max(far * 1e-4, camera.position.length() - 2 * meta.radius);
    camera.far = far;
    camera.updateProjectionMatrix();
    viewChanged();
  }

  // Frames every vertex (all the parts) from scene.view, leaving room for the colorbar.
  function resetView(redraw = true) {
    [view.elev, view.azim] = meta.view;
    view.elev = Math.max(-89.9, Math.min(89.9, view.elev));
    const [d, right, up] = axes(), P = positions, stride = Math.max(1, Math.floor(n / 50000));
    let u0 = Infinity, u1 = -Infinity, v0 = Infinity, v1 = -Infinity;
    for (let i = 0; i < n; i += stride) {
      const x = P[3 * i], y = P[3 * i + 1], z = P[3 * i + 2];
      const u = x * right.x + y * right.y, v = x * up.x + y * up.y + z * up.z;
      u0 = Math.min(u0, u); u1 = Math.max(u1, u); v0 = Math.min(v0, v); v1 = Math.max(v1, v);
    }
    const cu = (u0 + u1) / 2, cv = (v0 + v1) / 2;
    view.target = new THREE.Vector3().addScaledVector(right, cu).addScaledVector(up, cv);
    const box = $("o3h-view"), w = Math.max(box.clientWidth, 1), h = Math.max(box.clientHeight, 1);
    const tanV = Math.tan((FOV * Math.PI) / 360) * 0.92;
    const tanH = Math.tan((FOV * Math.PI) / 360) * ((w > 3 * CB_WIDTH ? w - CB_WIDTH : w) / h) * 0.94;
    const wt = view.target.dot(d);
    let dist = 0;
    for (let i = 0; i < n; i += stride) {
      const x = P[3 * i], y = P[3 * i + 1], z = P[3 * i + 2];
      const u = x * right.x + y * right.y - cu, v = x * up.x + y * up.y + z * up.z - cv;
      const depth = x * d.x + y * d.y + z * d.z - wt;
      dist = Math.max(dist, depth + Math.abs(u) / tanH, depth + Math.abs(v) / tanV);
    }
    view.dist = Math.max(dist, 1e-6 * meta.radius, 1e-30);
    placeCamera();
    if (redraw) draw();
  }

  function orbit(dx, dy) {
    view.azim -= dx * 0.4;
    view.elev = Math.max(-89.9, Math.min(89.9, view.elev + dy * 0.4));
    placeCamera();
    requestDraw();
  }

  function pan(dx, dy) {
    const [, right, up] = axes(), h = Math.max($("o3h-view").clientHeight, 1);
    const s = (2 * view.dist * Math.tan((FOV * Math.PI) / 360)) / h;
    view.target.addScaledVector(right, -dx * s).addScaledVector(up, dy * s);
    placeCamera();
    requestDraw();
  }

  function zoom(factor) {
    view.dist = Math.max(1e-4 * meta.radius, Math.min(100 * meta.radius, view.dist * factor));
    placeCamera();
    requestDraw();
  }

  // ------------------------------------------------------------------ picking
  let raycaster = null;
  function pick(clientX, clientY) {
    raycaster = raycaster || new THREE.Raycaster();
    const r = canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - r.left) / r.width) * 2 - 1, -((clientY - r.top) / r.height) * 2 + 1);
    raycaster.setFromCamera(ndc, camera);
    const hit = raycaster.intersectObject(mesh, false)[0];
    if (!hit) return -1;
    let best = -1, bd = Infinity;
    for (const v of [hit.face.a, hit.face.b, hit.face.c]) {
      const dx = positions[3 * v] - hit.point.x, dy = positions[3 * v + 1] - hit.point.y;
      const dz = positions[3 * v + 2] - hit.point.z, dd = dx * dx + dy * dy + dz * dz;
      if (dd < bd) { bd = dd; best = v; }
    }
    return best;
  }

  function showVertex(v, pinned) {
    if (v === readout.vertex && pinned === readout.pinned) return;
    readout.vertex = v;
    readout.pinned = pinned;
    updateReadout();
    requestDraw();
  }

  // ------------------------------------------------------------------ interaction
  function bindControls() {
    const pointers = new Map();
    let mode = null, moved = 0, pinch = 0, hoverTimer = 0;
    canvas.addEventListener("contextmenu", (e) => e.preventDefault());
    canvas.addEventListener("pointerdown", (e) => {
      canvas.setPointerCapture(e.pointerId);
      canvas.focus({ preventScroll: true });
      pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
      mode = e.button === 1 || e.button === 2 || e.shiftKey || e.ctrlKey || e.metaKey ? "pan" : "orbit";
      moved = pointers.size > 1 ? 99 : 0;
      canvas.style.cursor = "grabbing";
    });
    canvas.addEventListener("pointermove", (e) => {
      const p = pointers.get(e.pointerId);
      if (!p) { // hovering: read the vertex under the pointer once it rests
        if (readout.pinned || e.pointerType === "touch") return;
        clearTimeout(hoverTimer);
        hoverTimer = setTimeout(() => showVertex(pick(e.clientX, e.clientY), false), 60);
        return;
      }
      const dx = e.clientX - p.x, dy = e.clientY - p.y;
      p.x = e.clientX; p.y = e.clientY;
      moved += Math.abs(dx) + Math.abs(dy);
      if (pointers.size === 2) { // two fingers: pinch to zoom, move to pan
        const [a, b] = [...pointers.values()], d = Math.hypot(a.x - b.x, a.y - b.y);
        if (pinch > 0 && d > 0) zoom(pinch / d);
        pinch = d;
        pan(dx / 2, dy / 2);
      } else if (mode === "pan") pan(dx, dy);
      else orbit(dx, dy);
    });
    const up = (e) => {
      if (!pointers.has(e.pointerId)) return;
      pointers.delete(e.pointerId);
      pinch = 0;
      canvas.style.cursor = "grab";
      if (pointers.size === 0 && moved < 4 && e.type === "pointerup") { // a click: pin or release a vertex
        const v = pick(e.clientX, e.clientY);
        if (readout.pinned && v === readout.vertex) showVertex(-1, false); // a click on the pinned vertex releases it
        else showVertex(v, v >= 0);
      }
    };
    canvas.addEventListener("pointerup", up);
    canvas.addEventListener("pointercancel", up);
    canvas.addEventListener("pointerleave", () => { clearTimeout(hoverTimer); if (!readout.pinned) showVertex(-1, false); });
    canvas.addEventListener("wheel", (e) => {
      e.preventDefault();
      const dy = e.deltaY * (e.deltaMode === 1 ? 33 : e.deltaMode === 2 ? 400 : 1);
      zoom(Math.exp(Math.max(-200, Math.min(200, dy)) * 0.0015));
    }, { passive: false });
    canvas.addEventListener("keydown", (e) => {
      const k = e.key;
      if (k === "ArrowLeft") orbit(-12, 0);
      else if (k === "ArrowRight") orbit(12, 0);
      else if (k === "ArrowUp") orbit(0, -12);
      else if (k === "ArrowDown") orbit(0, 12);
      else if (k === "+" || k === "=") zoom(1 / 1.15);
      else if (k === "-" || k === "_") zoom(1.15);
      else if (k === "r" || k === "R") resetView();
      else return;
      e.preventDefault();
    });
    new ResizeObserver(() => { resize(); draw(); }).observe($("o3h-view"));
  }

  let playing = 0;
  function play(on) {
    clearInterval(playing);
    playing = 0;
    const b = $("o3h-play");
    b.textContent = on ? "❚❚" : "▶";
    b.setAttribute("aria-label", on ? "pause" : "play");
    if (!on) return;
    if (state.scale >= cur.meta.T - 1) api.setScale(0);
    playing = setInterval(() => {
      if (state.scale >= cur.meta.T - 1) play(false);
      else api.setScale(state.scale + 1);
    }, 450);
  }

  function bindUI() {
    $("o3h-scale").addEventListener("input", (e) => api.setScale(Number(e.target.value)));
    $("o3h-play").addEventListener("click", () => play(!playing));
    $("o3h-field").addEventListener("change", (e) => api.setField(meta.fields[Number(e.target.value)].name));
    $("o3h-global").addEventListener("change", (e) => api.setRange(e.target.checked ? "global" : "scale"));
    $("o3h-levels").addEventListener("change", (e) => api.setLevels(e.target.checked));
    $("o3h-markers").addEventListener("change", (e) => api.setMarkers(e.target.checked));
    $("o3h-tracks").addEventListener("change", (e) => api.setTracks(e.target.checked));
    $("o3h-life").addEventListener("input", (e) => {
      const k = Number(e.target.value), steps = cur.tracks.steps;
      api.setLifetime(k === 0 ? -Infinity : k <= steps.length ? steps[k - 1] : Infinity);
    });
    $("o3h-reset").addEventListener("click", () => resetView());
  }

  // ------------------------------------------------------------------ the scripting API
  function loaded() { if (!cur) throw new Error("the page is not ready (see o3dheat.ready, o3dheat.error)"); }
  Object.defineProperties(api, {
    scales: { get: () => (cur ? cur.meta.times.slice() : []), enumerable: true },
    scale: { get: () => state.scale, enumerable: true },
    field: { get: () => (cur ? cur.meta.name : null), enumerable: true },
    fields: { get: () => (meta ? meta.fields.map((f) => f.name) : []), enumerable: true },
  });
  api.setScale = function (i) {
    loaded();
    const T = cur.meta.T;
    if (!Number.isInteger(i) || i < -T || i >= T) throw new RangeError(`scale index must be an integer in [${-T}, ${T - 1}], got ${i}`);
    const t0 = performance.now();
    applyScale(i < 0 ? T + i : i);
    const t1 = performance.now();
    draw();
    api.timing.update = t1 - t0; // the page's own work (colours, level sets, markers, text)
    api.timing.submit = performance.now() - t1; // handing the frame to WebGL (not its drawing)
    return state.scale;
  };
  api.setField = function (name) {
    loaded();
    const i = meta.fields.findIndex((f) => f.name === name);
    if (i < 0) throw new RangeError(`no field named ${JSON.stringify(name)}; the fields: ${api.fields.join(", ")}`);
    selectField(i);
    draw();
    return name;
  };
  api.counts = function () {
    loaded();
    const c = cur.meta.counts[state.scale];
    return { minima: c[0], saddles: c[1], maxima: c[2] };
  };
  api.setRange = function (r) {
    loaded();
    if (r !== "global" && r !== "scale") throw new RangeError('range must be "global" or "scale"');
    state.global = r === "global";
    $("o3h-global").checked = state.global;
    applyScale(state.scale);
    draw();
  };
  api.setLevels = function (on) {
    loaded();
    state.levels = !!on && meta.levels > 0;
    $("o3h-levels").checked = state.levels;
    applyScale(state.scale);
    draw();
  };
  api.setMarkers = function (on) {
    loaded();
    state.markers = !!on;
    $("o3h-markers").checked = state.markers;
    updateMarkers();
    draw();
  };
  api.setTracks = function (on) {
    loaded();
    state.tracks = !!on;
    $("o3h-tracks").checked = state.tracks;
    buildTracks();
    draw();
  };
  api.setLifetime = function (x) {
    loaded();
    if (typeof x !== "number" || Number.isNaN(x)) throw new TypeError("the lifetime threshold must be a number");
    state.life = x;
    if (cur.tracks) { syncLifeSlider(); buildTracks(); }
    draw();
    return state.life;
  };
  api.resetView = () => { loaded(); resetView(); };
  Object.defineProperty(api, "deferred", { get: () => deferred.on, enumerable: true });
  api.setDeferred = function (on) { // a debugging switch: false draws every frame the plain way
    loaded();
    deferred.on = !!on && deferred.able;
    deferred.valid = false;
    clearTimeout(deferred.timer);
    draw(true);
    return deferred.on;
  };

  start().catch(fail);
})();
