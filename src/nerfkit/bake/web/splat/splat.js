// nerfkit's Gaussian-splat page: WebGL2, no build step, no network beyond its own folder.
//
// splats.bin holds N Gaussians x 16 RGBA32F texels (little-endian float32), the layout of
// nerfkit/bake/splat_web.py: texel 0 = (mean x, y, z, opacity), texel 1 = (Sxx, Sxy, Sxz, Syy),
// texel 2 = (Syz, Szz, 0, 0) (the 3D covariance), texels 3..14 = the 16 SH coefficients x RGB
// (coefficient k, channel c at float 12 + 3k + c). It is uploaded as one float texture, 256
// Gaussians per row. Each frame the Gaussians are sorted by view depth on the CPU (a 16-bit
// counting sort), and one quad per Gaussian is drawn back to front (premultiplied alpha, "over").
// The vertex shader projects as nerfkit/models/splat/project.py does (EWA, Jacobian at x/z, y/z clamped
// to 1.3 x the half-extent, + the run's screen dilation splats.json "dilation" in px^2 (3DGS: 0.3), 3-sigma
// square); the fragment shader evaluates alpha = min(0.99, o exp(-sigma)) at the pixel centre with the
// rasteriser's skip rules (sigma outside [0, 4.5] or alpha < 1/255). window.nerfkitSplat.render(camera)
// returns the RGBA8 pixels of exactly that camera (base64), for tests.
"use strict";

const TEXELS = 16, PER_ROW = 256;

const VS = `#version 300 es
precision highp float; precision highp int; precision highp sampler2D;
uniform sampler2D u_data;
uniform mat3 u_rot;      // world -> camera rotation (OpenCV axes: x right, y down, z forward)
uniform vec3 u_origin;   // camera centre (world)
uniform vec4 u_intr;     // fx, fy, cx, cy (pixels)
uniform vec2 u_size;     // width, height (pixels)
uniform int u_degree;
uniform float u_dilation; // px^2 added to the footprint's covariance (the run's --screen-dilation)
in uint a_index;
out vec3 v_color; out float v_opacity; out vec3 v_conic; out vec2 v_center;
vec4 texel(int g, int k) { int t = g * ${TEXELS} + k; return texelFetch(u_data, ivec2(t % ${TEXELS * PER_ROW}, t / ${TEXELS * PER_ROW}), 0); }
float coef(int g, int i) { int f = 12 + i; vec4 t = texel(g, f / 4); int c = f % 4; return c == 0 ? t.x : c == 1 ? t.y : c == 2 ? t.z : t.w; }
vec3 sh(int g, int k) { return vec3(coef(g, 3 * k), coef(g, 3 * k + 1), coef(g, 3 * k + 2)); }
void main() {
  int g = int(a_index);
  vec4 t0 = texel(g, 0), t1 = texel(g, 1), t2 = texel(g, 2);
  vec3 pc = u_rot * (t0.xyz - u_origin);
  gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // culled unless set below
  if (pc.z <= 0.01) return;
  mat3 S = mat3(t1.x, t1.y, t1.z, t1.y, t1.w, t2.x, t1.z, t2.x, t2.y);
  mat3 C = u_rot * S * transpose(u_rot);
  float fx = u_intr.x, fy = u_intr.y, cx = u_intr.z, cy = u_intr.w, z = pc.z;
  float tx = clamp(pc.x / z, -1.3 * cx / fx, 1.3 * (u_size.x - cx) / fx) * z;
  float ty = clamp(pc.y / z, -1.3 * cy / fy, 1.3 * (u_size.y - cy) / fy) * z;
  vec3 j0 = vec3(fx / z, 0.0, -fx * tx / (z * z)), j1 = vec3(0.0, fy / z, -fy * ty / (z * z));
  float a = dot(j0, C * j0) + u_dilation, b = dot(j0, C * j1), c = dot(j1, C * j1) + u_dilation;
  float det = a * c - b * b;
  if (det <= 0.0) return;
  float mid = 0.5 * (a + c), lam = mid + sqrt(max(mid * mid - det, 0.0));
  float r = ceil(3.0 * sqrt(lam));
  vec2 uv = vec2(fx * pc.x / z + cx, fy * pc.y / z + cy);
  if (uv.x + r <= 0.0 || uv.x - r >= u_size.x || uv.y + r <= 0.0 || uv.y - r >= u_size.y) return;
  vec2 corner = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1)) * 2.0 - 1.0;
  vec2 p = uv + corner * (r + 1.0);
  gl_Position = vec4(p.x / u_size.x * 2.0 - 1.0, 1.0 - p.y / u_size.y * 2.0, 0.0, 1.0);
  v_conic = vec3(c / det, -b / det, a / det);
  v_center = uv;
  v_opacity = t0.w;
  vec3 d = normalize(t0.xyz - u_origin);
  float x = d.x, y = d.y, zz = d.z;
  vec3 col = 0.28209479177387814 * sh(g, 0);
  if (u_degree > 0) col += -0.48860251190291987 * y * sh(g, 1) + 0.48860251190291987 * zz * sh(g, 2)
                        - 0.48860251190291987 * x * sh(g, 3);
  if (u_degree > 1) col += 1.0925484305920792 * x * y * sh(g, 4) - 1.0925484305920792 * y * zz * sh(g, 5)
      + (0.94617469575755997 * zz * zz - 0.31539156525251999) * sh(g, 6) - 1.0925484305920792 * x * zz * sh(g, 7)
      + 0.54627421529603959 * (x * x - y * y) * sh(g, 8);
  if (u_degree > 2) col += 0.59004358992664352 * y * (-3.0 * x * x + y * y) * sh(g, 9)
      + 2.8906114426405538 * x * y * zz * sh(g, 10) + 0.45704579946446572 * y * (1.0 - 5.0 * zz * zz) * sh(g, 11)
      + 0.3731763325901154 * zz * (5.0 * zz * zz - 3.0) * sh(g, 12)
      + 0.45704579946446572 * x * (1.0 - 5.0 * zz * zz) * sh(g, 13)
      + 1.4453057213202769 * zz * (x * x - y * y) * sh(g, 14) + 0.59004358992664352 * x * (-x * x + 3.0 * y * y) * sh(g, 15);
  v_color = max(col + 0.5, 0.0);
}`;

const FS = `#version 300 es
precision highp float;
uniform vec2 u_size;
in vec3 v_color; in float v_opacity; in vec3 v_conic; in vec2 v_center;
out vec4 o;
void main() {
  vec2 p = vec2(gl_FragCoord.x, u_size.y - gl_FragCoord.y);  // pixel centre (j + 0.5, i + 0.5)
  vec2 d = v_center - p;
  float s = 0.5 * (v_conic.x * d.x * d.x + v_conic.z * d.y * d.y) + v_conic.y * d.x * d.y;
  if (s < 0.0 || s > 4.5) discard;
  float alpha = min(0.99, v_opacity * exp(-s));
  if (alpha < 1.0 / 255.0) discard;
  o = vec4(v_color * alpha, alpha);
}`;

function compile(gl, type, src) {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

export class SplatRenderer {
  constructor(canvas, meta, floats) {
    const gl = canvas.getContext("webgl2", {antialias: false, premultipliedAlpha: false, preserveDrawingBuffer: true});
    if (!gl) throw new Error("WebGL2 is not available in this browser");
    this.gl = gl; this.canvas = canvas; this.meta = meta; this.n = meta.count;
    this.means = new Float32Array(this.n * 3);
    for (let i = 0; i < this.n; i++) for (let k = 0; k < 3; k++) this.means[3 * i + k] = floats[i * TEXELS * 4 + k];
    const prog = gl.createProgram();
    gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, VS));
    gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
    this.prog = prog;
    const rows = Math.ceil(this.n / PER_ROW);
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    const padded = new Float32Array(rows * PER_ROW * TEXELS * 4);
    padded.set(floats.subarray(0, Math.min(floats.length, padded.length)));
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, PER_ROW * TEXELS, rows, 0, gl.RGBA, gl.FLOAT, padded);
    this.order = new Uint32Array(this.n);
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    this.indexBuffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.indexBuffer);
    const loc = gl.getAttribLocation(prog, "a_index");
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribIPointer(loc, 1, gl.UNSIGNED_INT, 0, 0);
    gl.vertexAttribDivisor(loc, 1);
    this.u = {};
    for (const name of ["u_data", "u_rot", "u_origin", "u_intr", "u_size", "u_degree", "u_dilation"]) {
      this.u[name] = gl.getUniformLocation(prog, name);
    }
    this.depth = new Float32Array(this.n);
    this.counts = new Uint32Array(65536);
    this.keys = new Uint16Array(this.n);
  }

  // Indices of the Gaussians by decreasing view depth (far first), a 16-bit counting sort.
  sort(rot, origin) {
    const n = this.n, m = this.means, depth = this.depth;
    let lo = Infinity, hi = -Infinity;
    for (let i = 0; i < n; i++) {
      const z = rot[6] * (m[3 * i] - origin[0]) + rot[7] * (m[3 * i + 1] - origin[1]) + rot[8] * (m[3 * i + 2] - origin[2]);
      depth[i] = z; if (z < lo) lo = z; if (z > hi) hi = z;
    }
    const scale = hi > lo ? 65535 / (hi - lo) : 0, counts = this.counts, keys = this.keys;
    counts.fill(0);
    for (let i = 0; i < n; i++) { const k = 65535 - Math.floor((depth[i] - lo) * scale); keys[i] = k; counts[k]++; }
    for (let k = 1; k < 65536; k++) counts[k] += counts[k - 1];
    for (let i = n - 1; i >= 0; i--) this.order[--counts[keys[i]]] = i;
  }

  // Draw camera {c2w (4x4 rows, OpenGL camera-to-world), width, height, fx, fy, cx, cy}.
  draw(cam) {
    const gl = this.gl, c = cam.c2w;
    if (this.canvas.width !== cam.width || this.canvas.height !== cam.height) {
      this.canvas.width = cam.width; this.canvas.height = cam.height;
    }
    // world -> OpenCV camera: diag(1, -1, -1) R^T, row-major here
    const rot = [c[0][0], c[1][0], c[2][0], -c[0][1], -c[1][1], -c[2][1], -c[0][2], -c[1][2], -c[2][2]];
    const origin = [c[0][3], c[1][3], c[2][3]];
    this.sort(rot, origin);
    gl.viewport(0, 0, cam.width, cam.height);
    const bg = this.meta.background;
    gl.clearColor(bg[0], bg[1], bg[2], 1.0);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.useProgram(this.prog);
    gl.bindVertexArray(this.vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.indexBuffer);
    gl.bufferData(gl.ARRAY_BUFFER, this.order, gl.DYNAMIC_DRAW);
    gl.uniform1i(this.u.u_data, 0);
    gl.uniformMatrix3fv(this.u.u_rot, true, rot);  // row-major
    gl.uniform3fv(this.u.u_origin, origin);
    gl.uniform4f(this.u.u_intr, cam.fx, cam.fy, cam.cx, cam.cy);
    gl.uniform2f(this.u.u_size, cam.width, cam.height);
    gl.uniform1i(this.u.u_degree, this.meta.sh_degree);
    gl.uniform1f(this.u.u_dilation, this.meta.dilation ?? 0.3);  // pages baked before the setting: 0.3
    gl.enable(gl.BLEND);
    gl.blendFuncSeparate(gl.ONE, gl.ONE_MINUS_SRC_ALPHA, gl.ZERO, gl.ONE);  // colour "over", alpha stays 1
    gl.disable(gl.DEPTH_TEST);
    gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, this.n);
  }

  // RGBA8 pixels [H, W, 4], top row first.
  pixels(width, height) {
    const gl = this.gl, buf = new Uint8Array(width * height * 4), out = new Uint8Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, buf);
    for (let i = 0; i < height; i++) out.set(buf.subarray((height - 1 - i) * width * 4, (height - i) * width * 4), i * width * 4);
    return out;
  }
}
