// nerfkit baked scene renderer: WebGL2 ray marching of a nerfkit-baked-v1 brick grid (src/nerfkit/models/baked/format.py).
// The page (orbit camera, on-screen view, test API) is baked.js; this file exports window.nerfkitRender =
// {FORMAT, loadScene, Renderer}.
//
// Loading: baked.json and the three .npy arrays are fetched from the page's folder. The brick index
// [M, M, M] (int32) becomes an R32I 3D texture read with texelFetch. The K bricks of 9^3 vertex values
// are packed into 3D atlases of AW x AH x AD brick slots (brick k in slot (k % AW, k / AW % AH,
// k / (AW AH))): the log-density as R16F, the uint8 SH codes as ceil(C / 4) RGBA8 textures (channel c
// in texture c / 4, component c % 4), all with LINEAR filtering, so one hardware trilinear look-up at
// slot * 9 + local cell + fraction + 0.5 (texel centres) interpolates a cell's 8 vertices exactly as
// the format's trilinear(). Texture axes are the brick's (z, y, x): z varies fastest in the .npy
// arrays as in a 3D texture's rows.
//
// Rendering: a full-screen fragment shader marches each pixel's ray as the reference renderer
// (models/baked/model.py through render/chunked.py) does: d = R ((u - cx) / fx, -(v - cy) / fy, -1) at pixel
// centres, t_lo = max(near, box entry), t_hi = min(far, box exit), sample k on [t_lo + k step,
// min(t_lo + (k + 1) step, t_hi)] shaded at that interval's midpoint, sigma = exp(min(a, 15)),
// delta = interval length * |d|, colour = clip(sum_k coeff_k Y_k(d / |d|), 0, 1), stop once T < 1e-4,
// background composited. Empty bricks are skipped by jumping k to the first sample whose midpoint can
// lie past the brick (the samples are the same; only empty ones are not visited), and samples of
// weight T (1 - exp(-sigma delta)) below 1e-5 are left out of the sum, saving their colour look-ups
// (each moves a pixel by under 1/400 of an 8-bit level; 81 dB from the full sum on lego). The SH basis is
// constant along a ray, so each pixel first folds basis, dequantisation scale and offset into one
// 3x4 matrix per SH texture: a sample's colour is base + sum_t M_t * texture(sh_t, p).
"use strict";

(() => {
  const FORMAT = "nerfkit-baked-v1";
  const S = 9; // vertices per brick side (brick of 8 cells)
  const MIN_TRANSMITTANCE = 1e-4;

  // ---------------------------------------------------------------- .npy files

  /** {descr, shape, data (typed array)} of a little-endian, C-order .npy file's bytes. */
  function parseNpy(buf, name) {
    const u8 = new Uint8Array(buf);
    const magic = [0x93, 0x4e, 0x55, 0x4d, 0x50, 0x59]; // \x93NUMPY
    if (u8.length < 10 || magic.some((m, i) => u8[i] !== m)) throw new Error(`${name}: not a .npy file`);
    const major = u8[6];
    const view = new DataView(buf);
    const start = major === 1 ? 10 : 12;
    const hlen = major === 1 ? view.getUint16(8, true) : view.getUint32(8, true);
    const header = String.fromCharCode(...u8.subarray(start, start + hlen));
    const descr = /'descr':\s*'([^']+)'/.exec(header);
    const shape = /'shape':\s*\(([^)]*)\)/.exec(header);
    if (!descr || !shape) throw new Error(`${name}: unreadable .npy header ${header.trim()}`);
    if (/'fortran_order':\s*True/.test(header)) throw new Error(`${name}: Fortran-order arrays are not supported`);
    const types = {"<i4": Int32Array, "<f2": Uint16Array, "|u1": Uint8Array, "<u1": Uint8Array, "<f4": Float32Array};
    const Type = types[descr[1]];
    if (!Type) throw new Error(`${name}: dtype ${descr[1]} is not supported`);
    const dims = shape[1].split(",").map((s) => s.trim()).filter((s) => s).map(Number);
    const count = dims.reduce((a, b) => a * b, 1);
    const offset = start + hlen;
    if (offset + count * Type.BYTES_PER_ELEMENT > buf.byteLength) throw new Error(`${name}: file is truncated`);
    return {descr: descr[1], shape: dims, data: new Type(buf.slice(offset, offset + count * Type.BYTES_PER_ELEMENT))};
  }

  async function fetchOk(url) {
    const res = await fetch(url, {cache: "no-cache"});
    if (!res.ok) throw new Error(`${url}: HTTP ${res.status} ${res.statusText}`);
    return res;
  }

  /** The scene beside this page: meta, index, density, sh and the arrays' size in bytes. */
  async function loadScene() {
    const meta = await (await fetchOk("baked.json")).json();
    if (meta.format !== FORMAT) throw new Error(`baked.json: format ${meta.format}, expected ${FORMAT}`);
    const names = ["index", "density", "sh"];
    const bufs = await Promise.all(names.map(async (n) => (await fetchOk(`${n}.npy`)).arrayBuffer()));
    const [index, density, sh] = names.map((n, i) => parseNpy(bufs[i], `${n}.npy`));
    const n = meta.resolution, m = n / 8, bands = meta.sh_bands, c = 3 * bands * bands;
    const k = density.shape[0];
    const want = (a, shape) => a.shape.length === shape.length && a.shape.every((v, i) => v === shape[i]);
    if (meta.brick !== 8 || !want(index, [m, m, m]) || !want(density, [k, S, S, S]) || !want(sh, [k, S, S, S, c])
        || meta.sh_range.length !== c) {
      throw new Error(`array shapes ${JSON.stringify([index.shape, density.shape, sh.shape])} do not match ` +
                      `baked.json (resolution ${n}, sh_bands ${bands}); bake the scene again`);
    }
    if (index.descr !== "<i4" || density.descr !== "<f2" || !sh.descr.endsWith("u1")) {
      throw new Error(`array dtypes ${index.descr}, ${density.descr}, ${sh.descr}: expected int32, float16, uint8`);
    }
    return {meta, index, density, sh, bricks: k, channels: c, bytes: bufs.reduce((a, b) => a + b.byteLength, 0)};
  }

  // ---------------------------------------------------------------- textures

  /** Brick slots [AW, AH, AD] of an atlas for k bricks whose sides fit in maxSize texels. */
  function atlasLayout(k, maxSize) {
    const per = Math.floor(maxSize / S);
    if (k > per ** 3) throw new Error(`${k} bricks do not fit a ${maxSize}^3 texture atlas (MAX_3D_TEXTURE_SIZE)`);
    const w = Math.min(per, Math.max(1, Math.ceil(Math.cbrt(k))));
    const h = Math.min(per, Math.max(1, Math.ceil(Math.sqrt(k / w))));
    return [w, h, Math.max(1, Math.ceil(k / (w * h)))];
  }

  /** Atlas texel arrays: density (Uint16, half floats) and ceil(C / 4) RGBA8 arrays of SH codes. */
  function buildAtlases(scene, layout) {
    const [aw, ah, ad] = layout;
    const tw = aw * S, th = ah * S, td = ad * S;
    const c = scene.channels, nt = Math.ceil(c / 4);
    const dens = new Uint16Array(tw * th * td);
    const sh = Array.from({length: nt}, () => new Uint8Array(tw * th * td * 4));
    const src = scene.density.data, q = scene.sh.data;
    for (let id = 0; id < scene.bricks; id++) {
      const sw = id % aw, sv = Math.floor(id / aw) % ah, sd = Math.floor(id / (aw * ah));
      for (let x = 0; x < S; x++) {
        for (let y = 0; y < S; y++) {
          const from = ((id * S + x) * S + y) * S; // vertex (id, x, y, 0)
          const to = ((sd * S + x) * th + sv * S + y) * tw + sw * S; // texel (sw*9, sv*9 + y, sd*9 + x)
          dens.set(src.subarray(from, from + S), to);
          for (let z = 0; z < S; z++) {
            const qi = (from + z) * c, ti = (to + z) * 4;
            for (let j = 0; j < c; j++) sh[j >> 2][ti + (j & 3)] = q[qi + j];
          }
        }
      }
    }
    return {dens, sh, size: [tw, th, td]};
  }

  function texture3d(gl, unit, internal, format, type, size, data, filter) {
    const tex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(gl.TEXTURE_3D, tex);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage3D(gl.TEXTURE_3D, 0, internal, size[0], size[1], size[2], 0, format, type, data);
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_3D, p, filter);
    for (const p of [gl.TEXTURE_WRAP_S, gl.TEXTURE_WRAP_T, gl.TEXTURE_WRAP_R]) {
      gl.texParameteri(gl.TEXTURE_3D, p, gl.CLAMP_TO_EDGE);
    }
    return tex;
  }

  /** Upload the index, density and SH textures on units 0, 1 and 2.. ; returns the atlas layout. */
  function uploadScene(gl, scene) {
    const maxSize = gl.getParameter(gl.MAX_3D_TEXTURE_SIZE);
    const layout = atlasLayout(scene.bricks, maxSize);
    const atlas = buildAtlases(scene, layout);
    const m = scene.index.shape[0];
    texture3d(gl, 0, gl.R32I, gl.RED_INTEGER, gl.INT, [m, m, m], scene.index.data, gl.NEAREST);
    texture3d(gl, 1, gl.R16F, gl.RED, gl.HALF_FLOAT, atlas.size, atlas.dens, gl.LINEAR);
    atlas.sh.forEach((a, t) => texture3d(gl, 2 + t, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, atlas.size, a, gl.LINEAR));
    return {layout, size: atlas.size, maxSize};
  }

  // ---------------------------------------------------------------- shaders

  const VERTEX = `#version 300 es
void main() {  // one triangle covering the viewport
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}`;

  // Real SH basis of encoding/sh.py (tiny-cuda-nn's order and signs), bands 1..3.
  const SH_BASIS = [
    "0.28209479177387814",
    "-0.48860251190291987 * n.y", "0.48860251190291987 * n.z", "-0.48860251190291987 * n.x",
    "1.0925484305920792 * n.x * n.y", "-1.0925484305920792 * n.y * n.z",
    "0.94617469575755997 * n.z * n.z - 0.31539156525251999", "-1.0925484305920792 * n.x * n.z",
    "0.54627421529603959 * (n.x * n.x - n.y * n.y)",
  ];

  const lit = (x) => Number(x).toExponential(9);

  /** The fragment shader of one scene: SH textures, bands and dequantisation ranges are compiled in. */
  function fragmentSource(meta, layout) {
    const bands = meta.sh_bands, nb = bands * bands, c = 3 * nb, nt = Math.ceil(c / 4);
    if (!(bands >= 1 && bands <= 3)) throw new Error(`sh_bands ${bands}: this page renders 1 to 3 bands`);
    const lines = [];
    for (let k = 0; k < nb; k++) lines.push(`  float Y${k} = ${SH_BASIS[k]};`);
    for (let t = 0; t < nt; t++) lines.push(`  mat4x3 M${t} = mat4x3(0.0);`);
    for (let j = 0; j < c; j++) {
      const [lo, hi] = meta.sh_range[j];
      const t = j >> 2, col = j & 3, ch = Math.floor(j / nb), k = j % nb;
      lines.push(`  M${t}[${col}][${ch}] = ${lit(hi - lo)} * Y${k}; base[${ch}] += ${lit(lo)} * Y${k};`);
    }
    const samplers = Array.from({length: nt}, (_, t) => `uniform highp sampler3D uSH${t};`).join("\n");
    const fetches = Array.from({length: nt}, (_, t) => `M${t} * texture(uSH${t}, p)`).join(" + ");
    return `#version 300 es
precision highp float;
precision highp int;
uniform highp isampler3D uIndex;
uniform highp sampler3D uDensity;
${samplers}
uniform mat3 uRot;       // camera-to-world rotation
uniform vec3 uOrigin;    // camera centre
uniform vec4 uIntr;      // fx, fy, cx, cy
uniform float uHeight;   // viewport height, pixels
uniform vec3 uBackground;
out vec4 outColor;

const float B = ${lit(meta.bound)};
const int N = ${meta.resolution};
const float H = ${lit(2 * meta.bound / meta.resolution)};  // cell size
const float STEP = ${lit(meta.step)};
const float NEAR = ${lit(meta.near)};
const float FAR = ${lit(meta.far)};
const ivec3 SLOTS = ivec3(${layout.layout.join(", ")});
const vec3 INV_SIZE = vec3(${layout.size.map((v) => lit(1 / v)).join(", ")});

void main() {
  float u = gl_FragCoord.x, v = uHeight - gl_FragCoord.y;  // pixel centre, v from the top row
  vec3 d = uRot * vec3((u - uIntr.z) / uIntr.x, -(v - uIntr.w) / uIntr.y, -1.0);
  vec3 o = uOrigin;
  float dn = length(d);
  vec3 n = d / dn;
  vec3 base = vec3(0.0);
${lines.join("\n")}
  // Ray-box slabs as occupancy.ray_box_intersect (tiny direction components kept finite).
  vec3 dg = mix(d, sign(d + 1e-30) * 1e-12, lessThan(abs(d), vec3(1e-12)));
  vec3 ta = (-B - o) / dg, tb = (B - o) / dg;
  vec3 tmin = min(ta, tb), tmax = max(ta, tb);
  float tlo = max(NEAR, max(max(tmin.x, tmin.y), tmin.z));
  float thi = min(FAR, min(min(tmax.x, tmax.y), tmax.z));
  float T = 1.0, opacity = 0.0;
  vec3 acc = vec3(0.0);
  int k = 0;
  for (int it = 0; it < 1000000; it++) {
    float t0 = tlo + float(k) * STEP;
    if (!(t0 < thi)) break;
    float t1 = min(t0 + STEP, thi);
    vec3 g = (o + (0.5 * (t0 + t1)) * d + B) / H;  // the interval's midpoint, in cells
    if (any(lessThan(g, vec3(0.0))) || any(greaterThan(g, vec3(float(N))))) { k++; continue; }
    ivec3 cell = clamp(ivec3(floor(g)), ivec3(0), ivec3(N - 1));
    ivec3 b = cell >> 3;
    int id = texelFetch(uIndex, b.zyx, 0).r;
    if (id < 0) {  // empty brick: on to the first sample whose midpoint may lie past it
      vec3 lo = vec3(b * 8) * H - B;
      vec3 ea = (lo - o) / dg, eb = (lo + 8.0 * H - o) / dg;
      vec3 ex = max(ea, eb);
      float texit = min(min(ex.x, ex.y), ex.z);
      k = max(k + 1, int(floor((texit - tlo) / STEP - 0.51)) + 1);
      continue;
    }
    ivec3 slot = ivec3(id % SLOTS.x, (id / SLOTS.x) % SLOTS.y, id / (SLOTS.x * SLOTS.y));
    vec3 local = vec3(cell & 7) + clamp(g - vec3(cell), 0.0, 1.0) + 0.5;
    vec3 p = (vec3(slot * ${S}) + local.zyx) * INV_SIZE;
    float sigma = exp(min(texture(uDensity, p).r, 15.0));
    float tau = sigma * (t1 - t0) * dn;
    float alpha = 1.0 - exp(-tau);
    if (T * alpha > 1e-5) {  // fainter samples change no pixel: left out, saving their colour look-ups
      vec3 rgb = clamp(base + ${fetches}, 0.0, 1.0);
      float w = T * alpha;
      acc += w * rgb;
      opacity += w;
    }
    T *= exp(-tau);
    if (T < ${lit(MIN_TRANSMITTANCE)}) break;
    k++;
  }
  outColor = vec4(acc + (1.0 - opacity) * uBackground, 1.0);
}`;
  }

  function compile(gl, type, src) {
    const sh = gl.createShader(type);
    gl.shaderSource(sh, src);
    gl.compileShader(sh);
    if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw new Error(`shader: ${gl.getShaderInfoLog(sh)}`);
    return sh;
  }

  function makeProgram(gl, scene, layout) {
    const prog = gl.createProgram();
    gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, VERTEX));
    gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER, fragmentSource(scene.meta, layout)));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(`program: ${gl.getProgramInfoLog(prog)}`);
    gl.useProgram(prog);
    gl.uniform1i(gl.getUniformLocation(prog, "uIndex"), 0);
    gl.uniform1i(gl.getUniformLocation(prog, "uDensity"), 1);
    for (let t = 0; t < Math.ceil(scene.channels / 4); t++) gl.uniform1i(gl.getUniformLocation(prog, `uSH${t}`), 2 + t);
    const white = scene.meta.background === "white" ? 1 : 0;
    gl.uniform3f(gl.getUniformLocation(prog, "uBackground"), white, white, white);
    const loc = {};
    for (const name of ["uRot", "uOrigin", "uIntr", "uHeight"]) loc[name] = gl.getUniformLocation(prog, name);
    return {prog, loc};
  }

  // ---------------------------------------------------------------- renderer

  /** Draws camera views into offscreen RGBA8 framebuffers (reused per size). */
  class Renderer {
    constructor(gl, scene) {
      this.gl = gl;
      this.layout = uploadScene(gl, scene);
      Object.assign(this, makeProgram(gl, scene, this.layout));
      this.targets = new Map();
      this.pixel = new Uint8Array(4);
      const eye = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];
      this.draw({c2w: eye, fx: 1, fy: 1, cx: 0.5, cy: 0.5}, 1, 1); // compile the shader before timing frames
      this.sync();
    }

    target(width, height) {
      const key = `${width}x${height}`;
      if (!this.targets.has(key)) {
        const gl = this.gl;
        if (this.targets.size > 8) this.clearTargets();
        const tex = gl.createTexture();
        gl.activeTexture(gl.TEXTURE15);
        gl.bindTexture(gl.TEXTURE_2D, tex);
        gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA8, width, height);
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
        gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
        const fb = gl.createFramebuffer();
        gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
        gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
        gl.bindTexture(gl.TEXTURE_2D, null);
        this.targets.set(key, {fb, tex, width, height});
      }
      return this.targets.get(key);
    }

    clearTargets() {
      for (const t of this.targets.values()) {
        this.gl.deleteFramebuffer(t.fb);
        this.gl.deleteTexture(t.tex);
      }
      this.targets.clear();
    }

    /** Render camera {c2w (4x4 rows), fx, fy, cx, cy} into a width x height target; returns the target. */
    draw(cam, width, height) {
      const gl = this.gl, c = cam.c2w, tgt = this.target(width, height);
      gl.bindFramebuffer(gl.FRAMEBUFFER, tgt.fb);
      gl.viewport(0, 0, width, height);
      gl.useProgram(this.prog);
      gl.uniformMatrix3fv(this.loc.uRot, false, [c[0][0], c[1][0], c[2][0], c[0][1], c[1][1], c[2][1],
                                                 c[0][2], c[1][2], c[2][2]]);
      gl.uniform3f(this.loc.uOrigin, c[0][3], c[1][3], c[2][3]);
      gl.uniform4f(this.loc.uIntr, cam.fx, cam.fy, cam.cx, cam.cy);
      gl.uniform1f(this.loc.uHeight, height);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      return tgt;
    }

    /** Wait until the GPU has finished (a one-pixel read-back). */
    sync() {
      this.gl.readPixels(0, 0, 1, 1, this.gl.RGBA, this.gl.UNSIGNED_BYTE, this.pixel);
    }

    /** RGBA8 pixels [height, width, 4] of the bound target, top row first. */
    read(width, height) {
      const gl = this.gl, px = new Uint8Array(width * height * 4), out = new Uint8Array(width * height * 4);
      gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, px);
      const row = width * 4;
      for (let i = 0; i < height; i++) out.set(px.subarray((height - 1 - i) * row, (height - i) * row), i * row);
      return out;
    }
  }

  window.nerfkitRender = {FORMAT, loadScene, Renderer};
})();
