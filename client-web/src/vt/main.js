// The virtual-texturing demo (vt.html): a camera flies over a virtual texture lying on the ground
// plane; each frame a feedback pass names the pages the visible fragments need, the missing ones
// (and their coarser ancestors) stream from vtex — a page alone, or the page metatile (an aligned
// block of pages) where most of one is wanted: immutable URLs that a cache in front shares
// between clients — into an atlas of bordered pages, and the colour pass samples the atlas
// through the page table, blending the two levels around each fragment's level of detail; a page
// that arrives fades in over a few frames. With a light, each page's normal page (the server's
// `layer=normal`) comes with it into a second atlas, and the ground is lit.
//
// URL parameters: texture (id, name or id prefix; default the 100k chaos mosaic),
// camera=x,y,height,yaw,pitch (a fixed camera, drawn until every page it needs is resident;
// without it the camera flies, the same path at any frame rate), frames=N (draw N frames),
// format=rgba|bc7 (default bc7 where the GPU has BPTC), aniso=N (at most 4), slots=N (atlas
// slots a side, at least 5: the 21 pinned pages fit), feedback=N (the feedback buffer N times
// smaller than the view), light=azimuth,elevation|off (degrees: where the light comes from,
// azimuth 0 towards the texture's top (row 0), 90 its right; elevation above the ground; default
// 315,45; off: no normal pages fetched, the colour unlit).
// debug (shared/debug.js): `window.vtDemo` exposes the state and a log of every page requested,
// made resident or evicted and every fetch, or the error that stopped the demo.

import { MAX_ANISOTROPY, VtRenderer } from '../shared/vt-gl.js';
import { BORDER, PAGE_SIZE, decodeFeedback, pyramid } from '../shared/vt-pages.js';
import { PageStream, ServerPages } from '../shared/vt-stream.js';
import { findTexture } from '../shared/texture-lookup.js';
import { expose } from '../shared/debug.js';
import { GlPage, frameRate } from '../shared/gl-page.js';
import { getJson } from '../shared/http.js';

const FLAGSHIP = 'Pebbles — chaos mosaic 100k';
/** The fly-through: height above the ground and distance a frame, in level-0 texels. */
const FLIGHT = { height: 220, pitch: 20, step: 20, fov: 60 };
/** The light when `?light=` is not given: from the texture's top left, 45° up. */
const LIGHT = '315,45';

const page = new GlPage('vtDemo');
const { params, overlay, canvas } = page;
const fail = (message) => page.fail(message);
const number = (...args) => page.number(...args);

async function start() {
  const gl = page.webgl2();
  const list = await getJson('api/v1/textures', 'the texture list');
  const info = findTexture(list.textures, params.get('texture') || FLAGSHIP) || (!params.has('texture') && list.textures[0]);
  if (!info) fail(`no texture named ${params.get('texture')}`);

  const bptc = gl.getExtension('EXT_texture_compression_bptc');
  const format = params.get('format') || (bptc ? 'bc7' : 'rgba');
  if (format !== 'rgba' && format !== 'bc7') fail('?format= must be rgba or bc7');
  if (format === 'bc7' && !bptc) fail('this GPU has no BC7 (EXT_texture_compression_bptc): use ?format=rgba');
  const slotsPerSide = number('slots', 16, 5, Math.floor(gl.getParameter(gl.MAX_TEXTURE_SIZE) / (PAGE_SIZE + 2 * BORDER)));
  const frames = number('frames', Infinity, 1, 1e9);
  const light = lightDirection(params.get('light') ?? LIGHT);
  const renderer = new VtRenderer(gl, { feedbackScale: number('feedback', 8, 1, 32) });
  const texture = renderer.addTexture(pyramid(info), {
    slotsPerSide,
    bc7: format === 'bc7' ? bptc : null,
    anisotropy: number('aniso', MAX_ANISOTROPY, 1, MAX_ANISOTROPY),
    normals: light !== null,
  });
  const gpu = renderer.textures[texture];
  const surfaces = [renderer.ground(texture)];
  const stream = new PageStream(gpu, new ServerPages(info.id, format, { normals: light !== null }));

  const fixed = page.camera(FLIGHT.fov);
  const camera = fixed || { x: info.width / 2, y: info.height / 2, height: FLIGHT.height, yaw: 0, pitch: FLIGHT.pitch, fov: FLIGHT.fov };

  const state = {
    texture: info,
    format,
    anisotropy: gpu.anisotropy,
    light,
    frame: 0,
    log: stream.log,
    stats: stream.stats,
    frameMs: [], // from one frame's start to the next's
    cpuMs: [], // each frame's own work: feedback, read back, uploads, draw
    settled: false,
    done: false,
    get error() {
      return stream.error;
    },
  };

  await stream.pin();

  function draw() {
    if (!fixed) fly(camera, state.frame);
    const width = canvas.width;
    const height = canvas.height;
    const [needed] = decodeFeedback(renderer.feedback(camera, width, height, surfaces));
    state.frame++;
    stream.update(needed);
    if (stream.error) overlay.classList.add('error');
    renderer.draw(camera, width, height, surfaces, { light });
    state.needed = needed.size;
    showOverlay();
    return stream.idle;
  }

  function showOverlay() {
    overlay.textContent = [
      `${info.name} · ${format.toUpperCase()} pages ${PAGE_SIZE}² + ${BORDER} px border · trilinear, aniso ${gpu.anisotropy}× · ${light ? `lit from ${params.get('light') ?? LIGHT}` : 'unlit'}`,
      `resident ${stream.cache.size}/${stream.cache.slots.length} · needed ${state.needed} (missing ${state.stats.missing})`,
      `requested ${state.stats.requested} in ${state.stats.metatiles} metatiles · in flight ${stream.inFlight.size} · evicted ${state.stats.evicted} · ${(state.stats.bytes / 1e6).toFixed(1)} MB (${(state.stats.unused / 1e6).toFixed(1)} not asked for)`,
      `${frameRate(state)} · CPU ${(state.cpuMs.at(-1) ?? 0).toFixed(1)} ms the frame before`,
      state.error ? `error: ${state.error}` : '',
    ].join('\n');
  }

  expose('vtDemo', { state, cache: stream.cache, pyramid: gpu.pyramid, gpu, camera, resident: (key) => stream.cache.has(key) });
  // A fixed camera stops drawing once every page it needs is resident and drawn (unless a
  // number of frames is asked for).
  page.animate(state, { settles: fixed !== null && frames === Infinity, finished: () => state.frame >= frames, draw });
}

/**
 * `?light=`'s unit vector towards the light in world axes (texel x is world x, texel y world y,
 * the ground's normal +z), or null for `off`.
 */
function lightDirection(value) {
  if (value === 'off') return null;
  const v = value.split(',').map(Number);
  if (v.length !== 2 || v.some((d) => !Number.isFinite(d)) || v[1] <= 0 || v[1] > 90) fail('?light= must be azimuth,elevation (degrees, elevation above 0 up to 90) or off');
  const [azimuth, elevation] = v.map((d) => (d * Math.PI) / 180);
  return [Math.sin(azimuth) * Math.cos(elevation), -Math.cos(azimuth) * Math.cos(elevation), Math.sin(elevation)];
}

/** The fly-through at `frame`: forward a constant step a frame, turning slowly from side to side. */
function fly(camera, frame) {
  camera.yaw = 35 * Math.sin(frame / 540);
  const yaw = (camera.yaw * Math.PI) / 180;
  camera.x += Math.sin(yaw) * FLIGHT.step;
  camera.y -= Math.cos(yaw) * FLIGHT.step;
}

page.run(start);
