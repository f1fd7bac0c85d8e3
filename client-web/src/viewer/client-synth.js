// The viewer's client mode (`?synth=client`, or the Synthesis control): the texture's encoding
// is fetched once and every tile is synthesized in this browser, by Workers each running the
// WebAssembly module (shared/synth-workers.js), byte for byte the server's tile.
// Once the encoding is in, panning, zooming and animation need no server at all.
//
// A ClientSynth serves the tile sources of one texture (every animation frame): tilesource.js
// hands it OpenSeadragon's jobs (loadJobs, abortJob) instead of sending them to the server.

import { sourceTile } from './pyramid.js';
import { getJson } from '../shared/http.js';
import { SynthWorkers } from '../shared/synth-workers.js';

/** The synthesis of one texture (every animation frame) for its OpenSeadragon tile sources. */
export class ClientSynth extends SynthWorkers {
  /** Starts OpenSeadragon's `jobs` of the tile source of `context` (tilesource.js). */
  loadJobs(jobs, { info, frame, stats, inFlight }) {
    for (const job of jobs) {
      stats.started();
      inFlight.add(job);
      const t0 = performance.now();
      const t = sourceTile(info, job.tile);
      const request = this.tile(t.level, t.x, t.y, frame);
      job.userData = { ...job.userData, cancel: request.cancel };
      request.promise.then(
        ({ bitmap }) => {
          if (!inFlight.delete(job)) return bitmap.close();
          stats.loadedTile(performance.now() - t0, 0, null);
          job.finish(bitmap, null, 'imageBitmap');
        },
        (e) => {
          if (!inFlight.delete(job)) return;
          stats.failedTile(e.message);
          job.fail(e.message, null);
        },
      );
    }
  }

  /** Gives up `job`: its tile is no longer wanted. */
  abortJob(job, { inFlight, stats }) {
    if (!inFlight.delete(job)) return;
    job.userData.cancel();
    stats.abortedTile();
  }
}

/**
 * The description of a static export (`vtex export-web`), whose index.html names it in
 * `<meta name="vtex-export" content="…">`: { textures: [server-style info], encodings: { id →
 * bundle URL } }. Null when the page is served by vtex (no such meta).
 */
export async function staticExport() {
  const meta = document.querySelector('meta[name="vtex-export"]');
  if (!meta) return null;
  const url = new URL(meta.content, document.baseURI).href;
  return getJson(url, "the export's description");
}
