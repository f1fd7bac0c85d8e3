// Streaming one virtual texture's pages into its atlas (the VT demo and the 3D world): each frame
// the pages the feedback pass names are marked used, pages that arrived go into atlas slots
// (evicting the least recently used) and fade in over a few frames, and the missing ones and
// their coarser ancestors are asked of a page source — the server (`ServerPages`: a page alone,
// or the page metatile where most of one is wanted, immutable URLs that a cache in front shares
// between clients) or this browser (`SynthPages`: rendered from the encoding by the synthesis
// Workers).

import { FrameReader, readChunks } from './batch.js';
import { parseKtx2, VK_FORMAT_BC7_SRGB, VK_FORMAT_BC7_UNORM } from './ktx2.js';
import { fetchOk } from './http.js';
import { BORDER, FADE_FRAMES, PAGE_SIZE, PINNED_LEVELS, PageCache, fetchPlan, pageKey, plan } from './vt-pages.js';

/** Pages in flight at once from the server (so at most as many requests; the browser queues those past its connections). */
const SERVER_PAGES_IN_FLIGHT = 64;

/**
 * The page streaming of one virtual texture: `gpu` (vt-gl.js PhysicalTexture: its pyramid,
 * atlas and page table), a cache of its atlas's slots, and `source` (ServerPages or SynthPages).
 * `log` holds { frame, event: 'request' | 'resident' | 'evict' | 'drop' | 'fetch', key } — a
 * fetch's key is 'page L/x/y' or 'metatile L/x/y' — and `stats` the counts and page bytes.
 */
export class PageStream {
  constructor(gpu, source) {
    this.gpu = gpu;
    this.pyramid = gpu.pyramid;
    this.source = source;
    this.cache = new PageCache(gpu.slotsPerSide * gpu.slotsPerSide);
    this.frame = 0;
    this.inFlight = new Set();
    this.arrived = [];
    /** Pages fading in: key → { level, x, y, slot, until (the frame they show whole) }. */
    this.fading = new Map();
    this.log = [];
    // bytes: every page received; unused: those of pages a metatile brought that were not asked for.
    this.stats = { requested: 0, resident: 0, evicted: 0, bytes: 0, unused: 0, metatiles: 0, missing: 0 };
    /** The first error a page source met, or null. */
    this.error = null;
  }

  /** Fetches the coarsest levels and pins them: a fragment whose page is not resident falls back to them. */
  async pin() {
    const { maxLevel, grid } = this.pyramid;
    const pinned = [];
    for (let l = Math.max(0, maxLevel - PINNED_LEVELS + 1); l <= maxLevel; l++) {
      const [cols, rows] = grid(l);
      for (let y = 0; y < rows; y++) for (let x = 0; x < cols; x++) pinned.push({ key: pageKey(l, x, y), level: l, x, y });
    }
    await Promise.all(this.request(pinned));
    if (this.error) throw new Error(this.error);
    this.makeResident(true);
  }

  /**
   * One frame with the `needed` pages (decodeFeedback's Map for this texture): marks them used,
   * makes arrived pages resident and asks for the missing ones, no more than the atlas could take
   * now (a page that finds no slot is dropped). Answers how many needed pages are not resident.
   */
  update(needed) {
    this.frame++;
    this.gpu.frame = this.frame;
    const missing = this.cache.use(needed, this.frame, this.pyramid.maxLevel);
    this.fade();
    this.makeResident(false);
    this.stats.missing = missing;
    const room = Math.min(this.source.maxInFlight, this.cache.available(this.frame));
    const queue = plan(needed, (k) => this.cache.has(k), (k) => this.inFlight.has(k), this.pyramid.maxLevel);
    this.request(queue.slice(0, Math.max(0, room - this.inFlight.size)));
    return missing;
  }

  /** Whether nothing is missing, in flight, waiting to be made resident or fading in. */
  get idle() {
    return this.stats.missing === 0 && this.inFlight.size === 0 && this.arrived.length === 0 && this.fading.size === 0;
  }

  /** Marks the pages that have faded in whole as shown (the shader fades them by their age until then). */
  fade() {
    for (const [key, f] of this.fading) {
      if (this.frame < f.until) continue;
      this.gpu.map(f.level, f.x, f.y, f.slot);
      this.fading.delete(key);
    }
  }

  /** Asks the source for `pages` ({ key, level, x, y }, in priority order); answers the promises of the work started. */
  request(pages) {
    for (const p of pages) {
      this.inFlight.add(p.key);
      this.log.push({ frame: this.frame, event: 'request', key: p.key });
      this.stats.requested++;
    }
    return this.source.request(this, pages);
  }

  /**
   * Page (level, x, y) has come (`bytes` of it on the way): `body` is what its atlas slot takes,
   * `normal` what the normal atlas's does (when the texture has one).
   */
  take(level, x, y, body, bytes, normal) {
    this.stats.bytes += bytes;
    this.arrived.push({ key: pageKey(level, x, y), level, x, y, body, normal });
  }

  /** Pages of `wanted` (keys) that did not come, after `error` (or none): no longer in flight (and may be asked again). */
  settle(wanted, came, error) {
    if (error && !this.error) this.error = String(error);
    for (const key of wanted) {
      if (!came.has(key) && this.inFlight.delete(key)) this.log.push({ frame: this.frame, event: 'drop', key });
    }
  }

  /**
   * Puts arrived pages into the atlas and the page table, evicting least recently used ones; a
   * page streamed starts to fade in, a pinned one shows at once.
   */
  makeResident(pinned) {
    for (const page of this.arrived.splice(0)) {
      this.inFlight.delete(page.key);
      const placed = this.cache.insert(page, this.frame, pinned);
      if (!placed) {
        this.log.push({ frame: this.frame, event: 'drop', key: page.key });
        continue;
      }
      if (placed.evicted) {
        const e = placed.evicted;
        this.gpu.map(e.level, e.x, e.y, null);
        this.fading.delete(e.key);
        this.stats.evicted++;
        this.log.push({ frame: this.frame, event: 'evict', key: e.key });
      }
      this.gpu.upload(placed.slot, page.body, page.normal);
      const fades = !pinned && FADE_FRAMES > 1;
      this.gpu.map(page.level, page.x, page.y, placed.slot, fades ? this.frame : null);
      if (fades) this.fading.set(page.key, { level: page.level, x: page.x, y: page.y, slot: placed.slot, until: this.frame + FADE_FRAMES - 1 });
      this.stats.resident++;
      this.log.push({ frame: this.frame, event: 'resident', key: page.key });
    }
  }
}

/**
 * The server's page formats as the atlas takes them: URL extension and query, and the atlas's
 * upload of a page's bytes (`normal`: of the normal layer, linear).
 */
const PAGE_FORMATS = {
  rgba: { ext: 'rgba', codec: '', decode: (body) => body.slice() },
  bc7: { ext: 'ktx2', codec: 'codec=bc7&', decode: (body, normal) => bc7Blocks(body, normal ? VK_FORMAT_BC7_UNORM : VK_FORMAT_BC7_SRGB).slice() },
  // Decoded by the browser, as its pixels are: no colour management, no alpha premultiplied.
  jpg: { ext: 'jpg', codec: '', decode: (body) => createImageBitmap(new Blob([body], { type: 'image/jpeg' }), { colorSpaceConversion: 'none', premultiplyAlpha: 'none' }) },
};

/**
 * Pages of texture `id` from the server, as RGBA (`format` 'rgba'), BC7 KTX2 ('bc7') or JPEG
 * ('jpg', decoded here), of PAGE_SIZE with BORDER, at animation frame 0: grouped by fetchPlan, a
 * page alone or its page metatile; a page wanted while its metatile is on its way is taken from
 * it as it arrives. With `normals`, each fetch has its twin of the normal layer
 * (`layer=normal`), and a page comes once both halves have.
 */
export class ServerPages {
  constructor(id, format, { normals = false } = {}) {
    if (!PAGE_FORMATS[format]) throw new Error(`pages come as ${Object.keys(PAGE_FORMATS).join(', ')}, not ${format}`);
    this.id = id;
    this.format = PAGE_FORMATS[format];
    this.ext = this.format.ext;
    this.query = `${this.format.codec}size=${PAGE_SIZE}&border=${BORDER}`;
    this.layers = normals ? ['color', 'normal'] : ['color'];
    this.maxInFlight = SERVER_PAGES_IN_FLIGHT;
    /** Metatiles being fetched: key → the keys of the pages wanted from it. */
    this.fetching = new Map();
  }

  request(stream, pages) {
    const started = [];
    for (const { metatile, pages: group } of fetchPlan(pages, (k) => this.fetching.has(k))) {
      const joining = metatile && this.fetching.get(metatile.key);
      if (joining) {
        for (const p of group) joining.add(p.key);
        continue;
      }
      if (metatile) {
        const { level, x, y, key } = metatile;
        const wanted = new Set(group.map((p) => p.key));
        this.fetching.set(key, wanted);
        stream.stats.metatiles++;
        const path = `page-metatiles/${level}/${x}/${y}`;
        started.push(this.fetch(stream, `metatile ${key}`, path, wanted, readFrames).finally(() => this.fetching.delete(key)));
      } else {
        const { level, x, y, key } = group[0];
        const path = `pages/${level}/${x}/${y}`;
        started.push(this.fetch(stream, `page ${key}`, path, new Set([key]), async (r, take) => take(level, x, y, new Uint8Array(await r.arrayBuffer()))));
      }
    }
    return started;
  }

  /**
   * Fetches `path` (…/pages/L/x/y or …/page-metatiles/L/x/y, named `what` in the log) in each
   * layer, read by `read(response, take)`: each page `take`n that is `wanted` goes to the stream
   * once every layer has brought it, the others are left.
   */
  async fetch(stream, what, path, wanted, read) {
    const came = new Set();
    const halves = new Map(); // key → { bytes, [layer]: decoded pixels }
    const decoded = [];
    const taker = (layer) => (level, x, y, body) => {
      const key = pageKey(level, x, y);
      if (!wanted.has(key)) {
        stream.stats.bytes += body.length;
        stream.stats.unused += body.length;
        return;
      }
      decoded.push(
        Promise.resolve(this.format.decode(body, layer === 'normal')).then((pixels) => {
          const h = halves.get(key) || { bytes: 0 };
          h[layer] = pixels;
          h.bytes += body.length;
          halves.set(key, h);
          if (this.layers.every((l) => l in h)) {
            came.add(key);
            stream.take(level, x, y, h.color, h.bytes, h.normal);
          }
        }),
      );
    };
    let error = null;
    try {
      await Promise.all(
        this.layers.map(async (layer) => {
          const query = layer === 'color' ? this.query : `${this.query}&layer=${layer}`;
          stream.log.push({ frame: stream.frame, event: 'fetch', key: layer === 'color' ? what : `${what} ${layer}` });
          await read(await fetchOk(`api/v1/textures/${this.id}/${path}.${this.ext}?${query}`), taker(layer));
        }),
      );
      await Promise.all(decoded);
    } catch (e) {
      error = e;
    }
    stream.settle(wanted, came, error);
  }
}

/** A metatile's frames, each handed to `take` as it arrives. */
async function readFrames(r, take) {
  const reader = new FrameReader((f) => {
    if (f.status !== 200) throw new Error(`page ${f.level}/${f.x}/${f.y}: status ${f.status}`);
    take(f.level, f.x, f.y, f.body);
  });
  await readChunks(r.body, (c) => reader.push(c));
}

/** BC7 blocks of a KTX2 page of `vkFormat`. */
function bc7Blocks(ktx2, vkFormat) {
  const k = parseKtx2(ktx2);
  if (k.vkFormat !== vkFormat) throw new Error(`page is vkFormat ${k.vkFormat}, not ${vkFormat}`);
  return k.data(0);
}

/**
 * Pages rendered in this browser by `synth` (synth-workers.js SynthWorkers, the texture open in
 * it): page (level, x, y) is the region the server cuts it from — (x·PAGE_SIZE − BORDER,
 * y·PAGE_SIZE − BORDER), PAGE_SIZE + 2·BORDER a side, at animation frame 0 — so its RGBA bytes
 * are the server's RGBA page's.
 */
export class SynthPages {
  constructor(synth) {
    this.synth = synth;
    // Two a Worker: enough to keep each busy, few enough that the pages asked for stay those the view needs now.
    this.maxInFlight = 2 * synth.workerCount;
  }

  request(stream, pages) {
    const side = PAGE_SIZE + 2 * BORDER;
    return pages.map(async ({ key, level, x, y }) => {
      const came = new Set();
      let error = null;
      try {
        const at = (v) => v * PAGE_SIZE - BORDER;
        const { bytes } = await this.synth.region({ level, x: at(x), y: at(y), width: side, height: side, frame: 0 }).promise;
        came.add(key);
        stream.take(level, x, y, bytes, bytes.length);
      } catch (e) {
        error = e;
      }
      stream.settle([key], came, error);
    });
  }
}
