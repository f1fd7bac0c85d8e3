// The 3D world (world.html): a courtyard whose floor, walls and message board are virtual
// textures of different models, streamed page by page as the VT demo streams its ground (the same
// page cache, feedback pass, page tables and atlases: shared/vt-*.js). By default the pages are
// synthesized in this browser from the textures' encodings (one fetch each, then no texture
// traffic); `?pages=jpg|ktx2|rgba` fetches them from the server instead, for comparison.
//
// URL parameters: pages=client|jpg|ktx2|rgba (ktx2: BC7, where the GPU has it); floor, walls,
// board (a texture's id, name or id prefix for that surface; default a demo of its model,
// scene.js); camera=x,y,height,yaw,pitch (a fixed camera, drawn until every page it needs is
// resident); path=bench (the scripted walk once round, `frames` steps, default 240, starting once
// the first view is complete; without it and without a camera the walk loops); frames=N;
// slots=N (atlas slots a side, each texture); aniso=N; feedback=N.
// debug (shared/debug.js): `window.vtexWorld` exposes the state, each texture's stream (its log
// and cache) and `stats()`: frame times, bytes fetched by kind and the time to the first
// complete frame, for the tests and bench/world/run.mjs.

import { MAX_ANISOTROPY, VtRenderer } from '../shared/vt-gl.js';
import { BORDER, PAGE_SIZE, decodeFeedback, pyramid } from '../shared/vt-pages.js';
import { PageStream, ServerPages, SynthPages } from '../shared/vt-stream.js';
import { SynthWorkers } from '../shared/synth-workers.js';
import { findTexture } from '../shared/texture-lookup.js';
import { expose } from '../shared/debug.js';
import { GlPage, frameRate } from '../shared/gl-page.js';
import { getJson } from '../shared/http.js';
import { FOV, SURFACES, rectangles, walk } from './scene.js';

const PAGE_MODES = ['client', 'jpg', 'ktx2', 'rgba'];
const BENCH_STEPS = 240;

const page = new GlPage('vtexWorld');
const { params, overlay, canvas } = page;
const fail = (message) => page.fail(message);
const number = (...args) => page.number(...args);

/** The texture each surface shows (scene.js SURFACES): the URL's, else the preferred demo, else the first of its model that fits. */
function pickTextures(textures) {
  const fits = (t) => {
    try {
      return Boolean(pyramid(t));
    } catch {
      return false;
    }
  };
  return SURFACES.map((s) => {
    const named = params.get(s.param);
    const info = named
      ? findTexture(textures, named)
      : findTexture(textures, s.prefer) || textures.find((t) => t.model === s.model && fits(t));
    if (!info) fail(named ? `?${s.param}=: no texture named ${named}` : `no ${s.model} texture for the ${s.role}: the server has none`);
    return { ...s, info };
  });
}

/** Bytes on the wire since the page opened, by what they carried (Resource Timing). */
function transfers() {
  const bytes = { encodings: 0, module: 0, pages: 0, other: 0 };
  const requests = { encodings: 0, module: 0, pages: 0, other: 0 };
  for (const e of performance.getEntriesByType('resource')) {
    const path = new URL(e.name).pathname;
    const kind = /\/encoding$/.test(path) ? 'encodings' : /\.wasm$/.test(path) ? 'module' : /\/(pages|page-metatiles)\//.test(path) ? 'pages' : 'other';
    bytes[kind] += e.transferSize;
    requests[kind]++;
  }
  return { bytes, requests };
}

async function start() {
  performance.setResourceTimingBufferSize(1e6);
  const mode = params.get('pages') || 'client';
  if (!PAGE_MODES.includes(mode)) fail(`?pages= must be one of ${PAGE_MODES.join(', ')}`);
  const gl = page.webgl2();
  const bptc = gl.getExtension('EXT_texture_compression_bptc');
  if (mode === 'ktx2' && !bptc) fail('this GPU has no BC7 (EXT_texture_compression_bptc): use ?pages=rgba or ?pages=jpg');
  const surfaces = pickTextures((await getJson('api/v1/textures', 'the texture list')).textures);

  const slotsPerSide = number('slots', 16, 5, Math.floor(gl.getParameter(gl.MAX_TEXTURE_SIZE) / (PAGE_SIZE + 2 * BORDER)));
  const anisotropy = number('aniso', MAX_ANISOTROPY, 1, MAX_ANISOTROPY);
  const frames = number('frames', params.get('path') === 'bench' ? BENCH_STEPS : Infinity, 1, 1e9);
  if (params.has('path') && params.get('path') !== 'bench') fail('?path= must be bench');
  const renderer = new VtRenderer(gl, { feedbackScale: number('feedback', 8, 1, 32) });
  const streams = surfaces.map(({ info }) => {
    const texture = renderer.addTexture(pyramid(info), { slotsPerSide, bc7: mode === 'ktx2' ? bptc : null, anisotropy });
    const source = mode === 'client' ? new SynthPages(new SynthWorkers(info)) : new ServerPages(info.id, mode === 'ktx2' ? 'bc7' : mode);
    return new PageStream(renderer.textures[texture], source);
  });
  const index = Object.fromEntries(surfaces.map((s, i) => [s.role, i]));
  const sizes = Object.fromEntries(surfaces.map((s) => [s.role, s.info]));
  const drawn = [renderer.ground(index.floor), ...rectangles(sizes).map((r) => renderer.quad(index[r.role], r.corners, r.texels))];

  const fixed = page.camera(FOV);
  const steps = frames === Infinity ? 2 * BENCH_STEPS : frames;
  const camera = fixed || walk(0, steps);

  const state = {
    mode,
    textures: surfaces.map((s) => ({ role: s.role, id: s.info.id, name: s.info.name, model: s.info.model })),
    frame: 0,
    /** Steps of the walk taken: the walk starts once the first view is complete. */
    step: 0,
    /** Per step of the walk: the share of the pages it needed that were resident (a missing one is drawn from a coarser level). */
    residentShare: [],
    frameMs: [],
    cpuMs: [],
    /** ms from navigation start to the end of the first frame with every page it needs resident. */
    firstComplete: null,
    settled: false,
    done: false,
    get error() {
      return streams.find((s) => s.error)?.error ?? null;
    },
  };

  await Promise.all(streams.map((s) => s.pin()));

  function draw() {
    const walking = !fixed && state.firstComplete !== null;
    if (walking) Object.assign(camera, walk(++state.step % steps, steps));
    const width = canvas.width;
    const height = canvas.height;
    const needed = decodeFeedback(renderer.feedback(camera, width, height, drawn), streams.length);
    state.frame++;
    streams.forEach((s, i) => s.update(needed[i]));
    renderer.draw(camera, width, height, drawn);
    const complete = streams.every((s) => s.idle);
    if (complete && state.firstComplete === null) state.firstComplete = performance.now();
    if (walking) {
      const wanted = needed.reduce((n, m) => n + m.size, 0);
      const missing = streams.reduce((n, st) => n + st.stats.missing, 0);
      state.residentShare.push(wanted ? 1 - missing / wanted : 1);
    }
    if (state.error) overlay.classList.add('error');
    showOverlay(needed);
    return complete;
  }

  function showOverlay(needed) {
    const { bytes } = transfers();
    const kB = (b) => `${(b / 1e3).toFixed(0)} kB`;
    overlay.textContent = [
      `${mode === 'client' ? 'pages synthesized in this browser' : `${mode.toUpperCase()} pages from the server`} · ${PAGE_SIZE}² + ${BORDER} px border`,
      ...surfaces.map((s, i) => `${s.role}: ${s.info.name} · resident ${streams[i].cache.size} · needed ${needed[i].size} (missing ${streams[i].stats.missing}) · in flight ${streams[i].inFlight.size}`),
      `fetched: encodings ${kB(bytes.encodings)} · module ${kB(bytes.module)} · pages ${kB(bytes.pages)}`,
      `${frameRate(state)}${state.firstComplete === null ? '' : ` · first complete at ${(state.firstComplete / 1000).toFixed(2)} s`}`,
      state.error ? `error: ${state.error}` : '',
    ].join('\n');
  }

  /** The figures a bench reads: frame times, bytes and requests by kind, the first complete frame, the walk's resident shares. */
  const stats = () => ({ mode, frames: state.frame, steps: state.step, residentShare: state.residentShare.slice(), frameMs: state.frameMs.slice(), cpuMs: state.cpuMs.slice(), firstComplete: state.firstComplete, ...transfers(), error: state.error });
  expose('vtexWorld', { state, streams, camera, stats });
  page.animate(state, { settles: fixed !== null && frames === Infinity, finished: () => (fixed ? state.frame : state.step) >= frames, draw });
}

page.run(start);
