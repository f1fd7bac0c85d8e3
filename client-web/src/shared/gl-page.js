// What a WebGL page of virtual textures (vt.html, world.html) does around its drawing: reads its
// URL parameters, shows the message that stopped it in its overlay (and to its debugging hook),
// runs its frames and keeps its canvas the size it is shown at.

import { expose } from './debug.js';

export class GlPage {
  /** The page whose debugging hook is `window[hook]` (debug.js), its overlay the element #overlay. */
  constructor(hook) {
    this.hook = hook;
    this.params = new URLSearchParams(location.search);
    this.overlay = document.getElementById('overlay');
    this.canvas = document.getElementById('view');
    /** The message that stopped the page, once it has stopped. */
    this.failure = null;
  }

  /** Stops the page with `message`, shown in the overlay and as the hook's `error`. */
  fail(message) {
    this.failure = message;
    this.overlay.textContent = message;
    this.overlay.classList.add('error');
    expose(this.hook, { error: message });
    throw new Error(message);
  }

  /** Runs `start` (async), failing with whatever it throws that is not already the failure. */
  run(start) {
    start().catch((e) => {
      if (this.failure === null) this.fail(String(e));
    });
  }

  /** The canvas's WebGL2 context, its drawing kept for screenshots. */
  webgl2() {
    const gl = this.canvas.getContext('webgl2', { antialias: false, preserveDrawingBuffer: true });
    if (!gl) this.fail('This browser has no WebGL2.');
    return gl;
  }

  /** URL parameter `name` as a number from `min` to `max`, `fallback` when absent. */
  number(name, fallback, min, max) {
    if (!this.params.has(name)) return fallback;
    const v = Number(this.params.get(name));
    if (!Number.isFinite(v) || v < min || v > max) this.fail(`?${name}= must be a number from ${min} to ${max}`);
    return v;
  }

  /** The fixed camera `?camera=x,y,height,yaw,pitch` with field of view `fov`, or null. */
  camera(fov) {
    if (!this.params.has('camera')) return null;
    const c = this.params.get('camera').split(',').map(Number);
    if (c.length !== 5 || c.some((v) => !Number.isFinite(v)) || c[2] <= 0) this.fail('?camera= must be x,y,height,yaw,pitch (height > 0)');
    return { x: c[0], y: c[1], height: c[2], yaw: c[3], pitch: c[4], fov };
  }

  /**
   * Draws a frame with `draw()` at every animation frame — it answers whether the frame had every
   * page it needs — recording in `state` each frame's interval (`frameMs`) and own work (`cpuMs`).
   * With `settles` (a fixed camera) drawing stops once two frames in a row had every page
   * (`state.settled`), and starts again when the canvas is resized; it ends once `finished()`
   * (`state.done`). The canvas is kept the size it is shown at.
   */
  animate(state, { settles, finished, draw }) {
    let last = performance.now();
    let complete = 0;
    const step = (now) => {
      const t0 = performance.now();
      state.frameMs.push(now - last);
      last = now;
      complete = draw() ? complete + 1 : 0;
      state.cpuMs.push(performance.now() - t0);
      state.settled = settles && complete >= 2;
      state.done = finished();
      if (!state.settled && !state.done) requestAnimationFrame(step);
    };
    const fit = () => {
      this.canvas.width = Math.max(1, Math.round(this.canvas.clientWidth));
      this.canvas.height = Math.max(1, Math.round(this.canvas.clientHeight));
      if (state.settled) {
        state.settled = false;
        complete = 0;
        requestAnimationFrame(step);
      }
    };
    window.addEventListener('resize', fit);
    fit();
    requestAnimationFrame(step);
  }
}

/** The overlay's frame-rate line: the mean of the last 30 frame intervals of `state`, and the frame's number. */
export function frameRate(state) {
  const recent = state.frameMs.slice(-30);
  const mean = recent.reduce((a, b) => a + b, 0) / recent.length;
  return `frame ${mean.toFixed(1)} ms (${(1000 / mean).toFixed(0)} fps) · frame #${state.frame}`;
}
