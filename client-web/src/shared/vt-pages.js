// The bookkeeping of virtual texturing (the VT demo, vt.html, and the 3D world, world.html): the
// page pyramid of a texture, the physical page cache (atlas slots, LRU, pinned coarse levels), the
// feedback buffer's decoding and the plan of which pages to stream next. Pure functions and
// classes, tested in Node.

/** Page side and border asked of vtex: Unreal's default virtual-texture page. */
export const PAGE_SIZE = 128;
export const BORDER = 4;
/** Side of an atlas slot: the page and its border on every side. */
export const SLOT_SIDE = PAGE_SIZE + 2 * BORDER;
/** Page coordinates the feedback buffer can name: 12 bits a coordinate (and levels to 12, alpha's low nibble). */
export const MAX_TABLE_SIDE = 4096;
/** Levels kept resident from the start, counted from the coarsest: nothing is ever black. */
export const PINNED_LEVELS = 3;
/**
 * Frames over which a page that arrives fades in over what showed before (its coarser levels):
 * the frame changes by an eighth of the difference a frame, not all at once.
 */
export const FADE_FRAMES = 8;

/**
 * Pages a side of the server's page metatiles: 512 level pixels a side (`GET
 * …/page-metatiles/{level}/{x}/{y}`, docs/server.md). A metatile and a single page are both one
 * immutable URL that a cache in front of vtex shares between clients; the demo fetches the
 * metatile where it wants most of it (`fetchPlan`).
 */
export const METATILE_PAGES = Math.max(1, Math.floor(512 / PAGE_SIZE));

/** The key of page (level, x, y): "level/x/y", as the server's frames name pages. */
export function pageKey(level, x, y) {
  return `${level}/${x}/${y}`;
}

/** The page metatile holding page (level, x, y): { key, level, x, y } in the metatile grid. */
export function metatileOf(level, x, y) {
  const [mx, my] = [Math.floor(x / METATILE_PAGES), Math.floor(y / METATILE_PAGES)];
  return { key: pageKey(level, mx, my), level, x: mx, y: my };
}

/**
 * How to fetch `pages` ({ key, level, x, y }, in priority order): grouped by page metatile, a
 * group as its metatile when it wants at least half of a whole one or when that metatile is on
 * its way already (`fetching(key)`), else page by page — so no fetch brings more than twice the
 * bytes asked for. Answers [{ metatile, pages }] in the order of each group's first page,
 * `metatile` null for a single page.
 */
export function fetchPlan(pages, fetching) {
  const groups = new Map();
  for (const p of pages) {
    const m = metatileOf(p.level, p.x, p.y);
    if (!groups.has(m.key)) groups.set(m.key, { metatile: m, pages: [] });
    groups.get(m.key).pages.push(p);
  }
  return [...groups.values()].flatMap((g) => {
    if (fetching(g.metatile.key) || 2 * g.pages.length >= METATILE_PAGES * METATILE_PAGES) return [g];
    return g.pages.map((p) => ({ metatile: null, pages: [p] }));
  });
}

/**
 * The page pyramid of texture `info` ({ width, height }): vtex's level L is ⌈W/2^L⌉ × ⌈H/2^L⌉,
 * cut into pages of `size`². The page table is a mipmapped square of side `tableSide` (a power
 * of two ≥ level 0's page grid), its mip L the table of level L; `maxLevel` is its last mip,
 * where the whole level is one page.
 */
export function pyramid(info, size = PAGE_SIZE) {
  const grid = (level) => [
    Math.ceil(Math.ceil(info.width / 2 ** level) / size),
    Math.ceil(Math.ceil(info.height / 2 ** level) / size),
  ];
  const [cols, rows] = grid(0);
  let tableSide = 1;
  while (tableSide < Math.max(cols, rows)) tableSide *= 2;
  if (tableSide > MAX_TABLE_SIDE) throw new Error(`${info.width}×${info.height} needs more than ${MAX_TABLE_SIDE}² pages`);
  const maxLevel = Math.log2(tableSide);
  return { width: info.width, height: info.height, size, tableSide, maxLevel, grid };
}

/** The page of `level` that level-`from` page (x, y) lies in (`level` ≥ `from`). */
export function ancestor(from, x, y, level) {
  const d = 2 ** (level - from);
  return [Math.floor(x / d), Math.floor(y / d)];
}

/** Virtual textures one feedback buffer can name: the high nibble of its alpha. */
export const MAX_TEXTURES = 16;

/**
 * Decodes a feedback buffer (RGBA8 pixels as the feedback shader writes them: x and y's low
 * bytes in R and G, their high nibbles in B, level + 1 in alpha's low nibble and the texture's
 * index in its high one, 0 where no surface is seen) into one Map per texture (`textures` of
 * them) from page key to { level, x, y, count } (count: fragments asking for it).
 */
export function decodeFeedback(pixels, textures = 1) {
  const maps = Array.from({ length: textures }, () => new Map());
  for (let i = 0; i < pixels.length; i += 4) {
    const a = pixels[i + 3];
    if (a === 0) continue;
    const pages = maps[a >> 4];
    if (!pages) throw new Error(`the feedback names texture ${a >> 4} of ${textures}`);
    const level = (a & 15) - 1;
    const x = pixels[i] | ((pixels[i + 2] & 15) << 8);
    const y = pixels[i + 1] | ((pixels[i + 2] >> 4) << 8);
    const key = pageKey(level, x, y);
    const p = pages.get(key);
    if (p) p.count++;
    else pages.set(key, { level, x, y, count: 1 });
  }
  return maps;
}

/**
 * The physical page cache: `slots` atlas slots holding one bordered page each, by key. Pages of
 * the pinned levels are never evicted; the others leave least recently used first, and never a
 * page used in the current frame (its slot may be drawn from right now).
 */
export class PageCache {
  constructor(slots) {
    this.slots = Array.from({ length: slots }, () => null); // { key, level, x, y, pinned, used }
    this.bySlot = new Map(); // key → slot
    this.free = Array.from({ length: slots }, (_, i) => slots - 1 - i);
  }

  has(key) {
    return this.bySlot.has(key);
  }

  get size() {
    return this.bySlot.size;
  }

  /** Marks `key` as used in `frame`; false when it is not resident. */
  touch(key, frame) {
    const slot = this.bySlot.get(key);
    if (slot === undefined) return false;
    this.slots[slot].used = frame;
    return true;
  }

  /**
   * Marks the `needed` pages of `frame` (decodeFeedback's Map) as used, and every resident
   * coarser ancestor up to `maxLevel` (fragments fall back to them). Returns how many needed
   * pages are not resident.
   */
  use(needed, frame, maxLevel) {
    let missing = 0;
    for (const { level, x, y } of needed.values()) {
      if (!this.touch(pageKey(level, x, y), frame)) missing++;
      for (let l = level + 1; l <= maxLevel; l++) {
        const [ax, ay] = ancestor(level, x, y, l);
        this.touch(pageKey(l, ax, ay), frame);
      }
    }
    return missing;
  }

  /** Slots a page arriving in `frame` could take: free ones and those of unpinned pages not used in it. */
  available(frame) {
    let n = this.free.length;
    for (const s of this.slots) if (s && !s.pinned && s.used < frame) n++;
    return n;
  }

  /**
   * A slot for page `page` ({ key, level, x, y }) in `frame`: a free one, or the least recently
   * used unpinned page's, which is evicted and returned as `evicted`. Null when every slot is
   * pinned or used in this frame.
   */
  insert(page, frame, pinned = false) {
    let slot = this.free.pop();
    let evicted = null;
    if (slot === undefined) {
      let oldest = -1;
      for (let i = 0; i < this.slots.length; i++) {
        const s = this.slots[i];
        if (!s.pinned && s.used < frame && (oldest < 0 || s.used < this.slots[oldest].used)) oldest = i;
      }
      if (oldest < 0) return null;
      slot = oldest;
      evicted = this.slots[slot];
      this.bySlot.delete(evicted.key);
    }
    this.slots[slot] = { key: page.key, level: page.level, x: page.x, y: page.y, pinned, used: frame };
    this.bySlot.set(page.key, slot);
    return { slot, evicted };
  }
}

/**
 * The pages to stream next for the `needed` pages of a frame (decodeFeedback's Map): each page
 * and every coarser ancestor up to `maxLevel` that is neither resident nor in flight, coarsest
 * first (so the view sharpens level by level), then by how many fragments ask for it.
 */
export function plan(needed, isResident, isInFlight, maxLevel) {
  const wanted = new Map();
  for (const { level, x, y, count } of needed.values()) {
    for (let l = level; l <= maxLevel; l++) {
      const [ax, ay] = ancestor(level, x, y, l);
      const key = pageKey(l, ax, ay);
      if (isResident(key) || isInFlight(key)) continue;
      const w = wanted.get(key);
      if (w) w.count += count;
      else wanted.set(key, { key, level: l, x: ax, y: ay, count });
    }
  }
  return [...wanted.values()].sort((a, b) => b.level - a.level || b.count - a.count || (a.key < b.key ? -1 : 1));
}
