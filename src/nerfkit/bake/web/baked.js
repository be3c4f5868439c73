// nerfkit baked scene viewer page: orbit controls, the on-screen view and its frame-time readout, and the test
// API, over render.js (window.nerfkitRender: loading the scene and the WebGL2 ray-marching renderer).
//
// Test API (window.nerfkitBaked): ready (Promise of the scene's info), render({c2w, width, height, fx,
// fy, cx, cy}) -> Promise of base64 RGBA8 pixels, top row first; benchmark({width, height, frames,
// c2w?}) -> Promise of ms per frame (each frame synchronised by a pixel read-back); defaultCamera(w, h);
// view() is the on-screen orbit; draw() renders the on-screen view now and returns its ms.
"use strict";

(() => {
  const {loadScene, Renderer} = window.nerfkitRender;
  const FOV_Y = 40 * Math.PI / 180; // the default camera's vertical field of view
  const MOVING_MS = 40; // frame time aimed at while the camera moves
  const $ = (id) => document.getElementById(id);

  // ---------------------------------------------------------------- orbit camera

  const sub = (a, b) => a.map((v, i) => v - b[i]);
  const add = (a, b) => a.map((v, i) => v + b[i]);
  const scale = (a, s) => a.map((v) => v * s);
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const normalize = (a) => scale(a, 1 / Math.hypot(...a));
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

  /** Orbit about a target: azimuth / elevation in radians about the scene's up axis (meta.up, the
   *  training cameras' mean up; +z when absent), distance in scene units. It starts at meta.eye (the
   *  first training camera's position) when given, else at azimuth -45 deg, elevation 30 deg, 2.7 B. */
  class Orbit {
    constructor(meta) {
      this.bound = meta.bound;
      this.up = normalize(meta.up || [0, 0, 1]);
      const x = Math.abs(this.up[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
      this.e1 = normalize(sub(x, scale(this.up, dot(x, this.up))));
      this.e2 = cross(this.up, this.e1);
      this.eye = meta.eye;
      this.reset();
    }

    reset() {
      this.target = [0, 0, 0];
      this.azimuth = -0.25 * Math.PI;
      this.elevation = Math.PI / 6;
      this.distance = 2.7 * this.bound;
      if (this.eye && Math.hypot(...this.eye) > 1e-6) {
        const v = normalize(this.eye);
        this.distance = Math.hypot(...this.eye);
        this.elevation = Math.asin(Math.max(-1, Math.min(1, dot(v, this.up))));
        this.azimuth = Math.atan2(dot(v, this.e2), dot(v, this.e1));
      }
    }

    /** Camera-to-world [4][4] rows (OpenGL: the camera looks down its -z, +y up). */
    c2w() {
      const ce = Math.cos(this.elevation);
      const dir = add(add(scale(this.e1, ce * Math.cos(this.azimuth)), scale(this.e2, ce * Math.sin(this.azimuth))),
                      scale(this.up, Math.sin(this.elevation)));
      const eye = add(this.target, scale(dir, this.distance));
      const back = dir, right = normalize(cross(this.up, back)), up = cross(back, right);
      return [0, 1, 2].map((i) => [right[i], up[i], back[i], eye[i]]).concat([[0, 0, 0, 1]]);
    }

    /** The pinhole camera of this view for a width x height image (vertical field of view FOV_Y). */
    camera(width, height) {
      const f = 0.5 * height / Math.tan(0.5 * FOV_Y);
      return {c2w: this.c2w(), fx: f, fy: f, cx: 0.5 * width, cy: 0.5 * height, width, height};
    }

    rotate(dx, dy) {
      this.azimuth -= dx * 0.006;
      this.elevation = Math.max(-1.55, Math.min(1.55, this.elevation + dy * 0.006));
    }

    /** Move the target by (dx, dy) pixels of a view `height` pixels tall. */
    pan(dx, dy, height) {
      const c = this.c2w(), s = 2 * this.distance * Math.tan(0.5 * FOV_Y) / height;
      const right = [c[0][0], c[1][0], c[2][0]], up = [c[0][1], c[1][1], c[2][1]];
      this.target = add(this.target, add(scale(right, -dx * s), scale(up, dy * s)));
    }

    zoom(factor) {
      this.distance = Math.max(0.02 * this.bound, Math.min(30 * this.bound, this.distance * factor));
    }
  }

  // ---------------------------------------------------------------- page

  /** On-screen view: renders on demand (camera moves, resizes); while the camera moves, at a lower
   *  resolution when a full frame would take over MOVING_MS, then at full resolution once it stops. */
  class View {
    constructor(canvas, renderer, orbit) {
      Object.assign(this, {canvas, renderer, orbit, gl: renderer.gl});
      this.scale = Number($("scale").value);
      this.moving = false;
      this.pending = false;
      this.msPerPixel = null; // smoothed frame time per pixel, for the resolution while moving
      this.pointers = new Map();
      this.bindEvents();
      this.request();
    }

    request() {
      if (!this.pending) {
        this.pending = true;
        requestAnimationFrame(() => {
          this.pending = false;
          this.draw();
        });
      }
    }

    /** Mark the camera as moving (until 200 ms without input). */
    moved() {
      this.moving = true;
      clearTimeout(this.still);
      this.still = setTimeout(() => {
        this.moving = false;
        this.request();
      }, 200);
      this.request();
    }

    /** Render the current view into the canvas; returns the frame's milliseconds. */
    draw() {
      const gl = this.gl, dpr = window.devicePixelRatio || 1;
      const cw = Math.max(1, Math.round(this.canvas.clientWidth * dpr));
      const ch = Math.max(1, Math.round(this.canvas.clientHeight * dpr));
      if (this.canvas.width !== cw || this.canvas.height !== ch) [this.canvas.width, this.canvas.height] = [cw, ch];
      let s = this.scale;
      if (this.moving && this.msPerPixel) { // fewer pixels while moving when a full frame would be slow
        s = Math.min(s, Math.max(0.1, Math.sqrt(MOVING_MS / (this.msPerPixel * cw * ch))));
      }
      const w = Math.max(1, Math.round(cw * s)), h = Math.max(1, Math.round(ch * s));
      const t0 = performance.now();
      const tgt = this.renderer.draw(this.orbit.camera(w, h), w, h);
      this.renderer.sync();
      const ms = performance.now() - t0;
      gl.bindFramebuffer(gl.READ_FRAMEBUFFER, tgt.fb);
      gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, null);
      gl.blitFramebuffer(0, 0, w, h, 0, 0, cw, ch, gl.COLOR_BUFFER_BIT, gl.LINEAR);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      if (s === this.scale) { // full frames only: small frames' fixed costs would inflate the per-pixel time
        const perPixel = ms / (w * h);
        this.msPerPixel = this.msPerPixel ? 0.5 * this.msPerPixel + 0.5 * perPixel : perPixel;
      }
      $("timing").textContent = `${ms.toFixed(1)} ms/frame · ${(1000 / ms).toFixed(1)} fps · ${w}×${h}`;
      return ms;
    }

    bindEvents() {
      const c = this.canvas;
      c.addEventListener("contextmenu", (e) => e.preventDefault());
      c.addEventListener("pointerdown", (e) => {
        c.setPointerCapture(e.pointerId);
        this.pointers.set(e.pointerId, {x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey});
      });
      const up = (e) => this.pointers.delete(e.pointerId);
      c.addEventListener("pointerup", up);
      c.addEventListener("pointercancel", up);
      c.addEventListener("pointermove", (e) => this.onMove(e));
      c.addEventListener("wheel", (e) => {
        e.preventDefault();
        const px = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? 400 : 1;
        this.orbit.zoom(Math.exp(e.deltaY * px * 0.0015));
        this.moved();
      }, {passive: false});
      c.addEventListener("dblclick", () => this.reset());
      $("reset").addEventListener("click", () => this.reset());
      $("scale").addEventListener("change", (e) => {
        this.scale = Number(e.target.value);
        this.request();
      });
      window.addEventListener("resize", () => this.request());
    }

    reset() {
      this.orbit.reset();
      this.request();
    }

    onMove(e) {
      const p = this.pointers.get(e.pointerId);
      if (!p) return;
      const dx = e.clientX - p.x, dy = e.clientY - p.y;
      const h = this.canvas.clientHeight;
      if (this.pointers.size >= 2) { // pinch: zoom by the change of finger distance, pan by half the motion
        const other = [...this.pointers.entries()].find(([id]) => id !== e.pointerId)[1];
        const before = Math.hypot(other.x - p.x, other.y - p.y);
        const after = Math.hypot(other.x - e.clientX, other.y - e.clientY);
        if (before > 0 && after > 0) this.orbit.zoom(before / after);
        this.orbit.pan(dx / 2, dy / 2, h);
      } else if (p.pan || e.shiftKey) {
        this.orbit.pan(dx, dy, h);
      } else {
        this.orbit.rotate(dx, dy);
      }
      p.x = e.clientX;
      p.y = e.clientY;
      this.moved();
    }
  }

  function toBase64(u8) {
    let s = "";
    for (let i = 0; i < u8.length; i += 0x8000) s += String.fromCharCode.apply(null, u8.subarray(i, i + 0x8000));
    return btoa(s);
  }

  function showStatus(text, error) {
    const el = $("status");
    el.textContent = text;
    el.className = error ? "hud error" : "hud";
    el.style.display = text ? "" : "none";
  }

  async function start() {
    const canvas = $("view");
    const gl = canvas.getContext("webgl2", {antialias: false, depth: false, alpha: false});
    if (!gl) throw new Error("this browser has no WebGL2 (try another browser, or enable hardware acceleration)");
    const scene = await loadScene();
    const renderer = new Renderer(gl, scene);
    const orbit = new Orbit(scene.meta);
    const mb = scene.bytes / 2 ** 20;
    $("scene").textContent = `· ${scene.bricks} bricks · ${scene.meta.resolution}³ · ${mb.toFixed(1)} MB`;
    showStatus("");
    const view = new View(canvas, renderer, orbit);
    return {scene, renderer, orbit, view, info: {bricks: scene.bricks, mb, resolution: scene.meta.resolution,
                                               sh_bands: scene.meta.sh_bands, atlas: renderer.layout.size,
                                               max3d: renderer.layout.maxSize}};
  }

  const started = start();
  started.catch((e) => showStatus(`cannot show the baked scene: ${e.message}`, true));

  window.nerfkitBaked = {
    ready: started.then((s) => s.info),

    /** Base64 RGBA8 pixels (top row first) of camera {c2w, width, height, fx, fy, cx, cy}. */
    async render(cam) {
      const {renderer} = await started;
      renderer.draw(cam, cam.width, cam.height);
      const px = renderer.read(cam.width, cam.height);
      renderer.gl.bindFramebuffer(renderer.gl.FRAMEBUFFER, null);
      return toBase64(px);
    },

    /** Mean milliseconds per frame of `frames` renders of width x height (default camera unless c2w given). */
    async benchmark({width = 800, height = 800, frames = 5, c2w = null} = {}) {
      const {renderer, orbit} = await started;
      const cam = orbit.camera(width, height);
      if (c2w) cam.c2w = c2w;
      renderer.draw(cam, width, height);
      renderer.sync();
      const t0 = performance.now();
      for (let i = 0; i < frames; i++) {
        renderer.draw(cam, width, height);
        renderer.sync();
      }
      return (performance.now() - t0) / frames;
    },

    /** The default orbit camera {c2w, fx, fy, cx, cy, width, height} for a width x height image. */
    async defaultCamera(width, height) {
      const {scene} = await started;
      return new Orbit(scene.meta).camera(width, height);
    },

    /** The on-screen view's orbit: {c2w, target, distance, azimuth, elevation}. */
    async view() {
      const {orbit} = await started;
      const {target, distance, azimuth, elevation} = orbit;
      return {c2w: orbit.c2w(), target, distance, azimuth, elevation};
    },

    /** Render the on-screen view now, at full resolution; returns its milliseconds. */
    async draw() {
      const {view} = await started;
      clearTimeout(view.still);
      view.moving = false;
      return view.draw();
    },
  };
})();
