// The network side of the tiles, in a dedicated Worker (viewer/tilesource.js starts it): fetches a
// metatile (or any body of tile frames), splits it into frames (shared/batch.js) and turns each
// tile the page wants into an ImageBitmap that it transfers to the page. On the page's main thread the body could only be read between
// animation frames, each busy with canvas raster and OpenSeadragon's update while a view loads,
// so a view's bytes would trickle in over several frames. Here they flow while the page draws.
//
// Messages in:  { type: 'load', id, url, format, want }   { type: 'abort', id }
//               (`want`: the "level/x/y" keys of the tiles to decode; the others are skipped)
// Messages out: { type: 'tiles', id, tiles: [{ level, x, y, status, cache, length, arrived,
//                 bitmap | error }] }  (the tiles of one chunk of the body, together: one task
//                 on the page for all of them, so a frame cannot fall between them)
//               { type: 'timing', entry }   (Resource Timing of a batch, times on `origin`'s clock)
//               { type: 'end', id, error }  (after the batch's last tile; error null if complete)
// `arrived` (the frame was complete) and the timing entry are on the worker's clock shifted to
// the epoch (performance.timeOrigin + now); the page shifts them back to its own.

import { FrameReader, readChunks, tileKey } from '../shared/batch.js';
import { opaqueBitmap } from './opaque-bitmap.js';
import { errorText, fetchOk } from '../shared/http.js';

/** Read buffers of the batches that finished, for the next ones (shared/batch.js readChunks). */
const readBuffers = [];
/** Batches in flight: id → AbortController. */
const inFlight = new Map();

self.onmessage = ({ data }) => {
  if (data.type === 'load') load(data);
  else if (data.type === 'abort') inFlight.get(data.id)?.abort();
};

// Bytes on the wire of every batch (the page's statistics and bench/viewer/trace.mjs): the
// Worker's fetches only, whatever else its timeline may hold (its module imports).
new PerformanceObserver((list) => {
  for (const e of list.getEntries()) {
    if (e.initiatorType !== 'fetch') continue;
    const shift = (t) => performance.timeOrigin + t;
    self.postMessage({
      type: 'timing',
      entry: {
        name: e.name,
        transferSize: e.transferSize,
        decodedBodySize: e.decodedBodySize,
        fetchStart: shift(e.fetchStart),
        requestStart: shift(e.requestStart),
        responseStart: shift(e.responseStart),
        responseEnd: shift(e.responseEnd),
      },
    });
  }
  performance.clearResourceTimings();
}).observe({ type: 'resource' });

async function load({ id, url, format, want }) {
  const controller = new AbortController();
  inFlight.set(id, controller);
  const sent = [];
  let error = null;
  try {
    const response = await fetchOk(url, '', { signal: controller.signal, credentials: 'same-origin' });
    // Chunks and split frames live in buffers that are reused: each tile takes its bytes
    // while its frame is handed over (tileBitmap and errorText copy at once).
    let tiles = [];
    const wanted = new Set(want);
    // A metatile's frames tell no cache state; its response does, for all of them.
    const cache = response.headers.get('x-vtex-cache');
    const reader = new FrameReader(
      (f) => {
        if (wanted.has(tileKey(f.level, f.x, f.y))) tiles.push(tileMessage({ ...f, cache: f.cache || cache }, format));
      },
      { reuse: true },
    );
    await readChunks(
      response.body,
      (chunk) => {
        reader.push(chunk);
        if (tiles.length) sent.push(postTiles(id, tiles));
        tiles = [];
      },
      readBuffers,
    );
    if (!reader.complete) error = 'the response ended inside a tile frame';
  } catch (e) {
    error = e && e.name === 'AbortError' ? 'aborted' : String(e && e.message ? e.message : e);
  } finally {
    inFlight.delete(id);
  }
  await Promise.all(sent);
  self.postMessage({ type: 'end', id, error });
}

/** Posts `tiles` (promises of tile messages) in one message, their bitmaps transferred. */
async function postTiles(id, tiles) {
  const done = await Promise.all(tiles);
  self.postMessage({ type: 'tiles', id, tiles: done }, done.flatMap((t) => (t.bitmap ? [t.bitmap] : [])));
}

/** The tile of frame `f` as the page gets it: its bitmap, or why there is none. */
function tileMessage(f, format) {
  const head = { level: f.level, x: f.x, y: f.y, status: f.status, cache: f.cache, length: f.body.length };
  head.arrived = performance.timeOrigin + performance.now();
  if (f.status !== 200) {
    return Promise.resolve({ ...head, error: `HTTP ${f.status} for tile ${f.level}/${f.x}/${f.y}: ${errorText(f.body)}` });
  }
  let bitmap;
  try {
    bitmap = format === 'rgba' ? rgbaTile(f) : encodedTile(f, format);
  } catch (e) {
    bitmap = Promise.reject(e);
  }
  return bitmap.then(
    (b) => ({ ...head, bitmap: b }),
    (e) => ({ ...head, error: `tile ${f.level}/${f.x}/${f.y}: ${e.message}` }),
  );
}

const MIME = { png: 'image/png', webp: 'image/webp', jpg: 'image/jpeg' };

/** An encoded tile (PNG, WebP, JPEG) as an ImageBitmap, decoded off the main thread. */
function encodedTile(f, format) {
  return createImageBitmap(new Blob([f.body], { type: MIME[format] })); // the Blob copies the bytes
}

/** A raw RGBA tile as an opaque ImageBitmap (opaque-bitmap.js), its size from the frame header. */
function rgbaTile(f) {
  const { width: w, height: h, body } = f;
  if (!(w > 0 && h > 0) || body.length !== w * h * 4) {
    throw new Error(`raw tile of ${body.length} bytes does not match ${w} × ${h} RGBA`);
  }
  return Promise.resolve(opaqueBitmap(body, w, h));
}
