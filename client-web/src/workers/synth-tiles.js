// One synthesis Worker of client synthesis (shared/synth-workers.js starts several): opens the
// texture's encoding in its own instance of the WebAssembly module and renders the jobs it is
// given, one at a time: tiles as opaque ImageBitmaps (opaque-bitmap.js, as raw RGBA tiles from
// the server) or as raw bytes when asked for them (the tests compare those), and regions (the 3D
// world's pages) as raw bytes.
//
// Messages in:  { type: 'open', module (WebAssembly.Module), bundle (ArrayBuffer), tileSize }
//               { type: 'tile', key, level, x, y, frame, raw }
//               { type: 'region', key, level, x, y, width, height, frame }   { type: 'cancel', key }
// Messages out: { type: 'opened', info } | { type: 'failed', error }
//               { type: 'tile', key, ms, bitmap | bytes, width, height } | { type: 'tile', key, error }

import { opaqueBitmap } from './opaque-bitmap.js';
import { instantiate } from '../shared/vtex-synth.js';

let texture = null;
/** Tiles waiting, in arrival order: key → message. Cancelling one deletes it. */
const queue = new Map();
let scheduled = false;

self.onmessage = ({ data }) => {
  if (data.type === 'open') open(data);
  else if (data.type === 'tile' || data.type === 'region') {
    queue.set(data.key, data);
    schedule();
  } else if (data.type === 'cancel') queue.delete(data.key);
};

async function open({ module, bundle, tileSize }) {
  try {
    const synth = await instantiate(module);
    texture = synth.open(new Uint8Array(bundle), tileSize);
    self.postMessage({ type: 'opened', info: texture.info });
    schedule();
  } catch (e) {
    self.postMessage({ type: 'failed', error: e.message || String(e) });
  }
}

/** Renders the next tile in a task of its own, so cancellations that arrive between tiles count. */
function schedule() {
  if (scheduled || !texture || queue.size === 0) return;
  scheduled = true;
  setTimeout(() => {
    scheduled = false;
    const [key, job] = queue.entries().next().value;
    queue.delete(key);
    render(job);
    schedule();
  }, 0);
}

function render({ type, key, level, x, y, width: w, height: h, frame, raw }) {
  const t0 = performance.now();
  let tile;
  try {
    tile = type === 'region' ? { width: w, height: h, data: texture.render({ level, x, y, width: w, height: h, frame }) } : texture.renderTile(level, x, y, frame);
  } catch (e) {
    self.postMessage({ type: 'tile', key, error: `${type} ${level}/${x}/${y}: ${e.message}` });
    return;
  }
  const { width, height, data } = tile;
  if (raw || type === 'region') {
    self.postMessage({ type: 'tile', key, ms: performance.now() - t0, bytes: data, width, height }, [data.buffer]);
    return;
  }
  const bitmap = opaqueBitmap(data, width, height);
  self.postMessage({ type: 'tile', key, ms: performance.now() - t0, bitmap, width, height }, [bitmap]);
}
