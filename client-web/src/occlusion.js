// Tiles a canvas frame need not draw: those that opaque tiles drawn after them in the same
// frame paint over entirely — and the parts of tiles they paint over.
//
// While a view loads, OpenSeadragon draws every loaded tile of every level down to one that
// covers the view, coarsest first: the whole-texture tile magnified across the whole view, then
// the preview level, then the finest tiles on top (loader.js fetches those three). On the
// software canvas every drawn pixel is rastered (bilinear) on the page's main thread, and the
// finest tiles paint over most of what the coarser ones drew. Skipping a tile changes nothing
// on screen when every pixel it would touch is afterwards overwritten whole by an opaque tile:
// the last full overwrite of a pixel decides its value, whatever was under it; so does drawing
// a tile clipped to the pixels nothing overwrites later. In the frames of 60 view loads where
// this applies, it rasters 0.67 instead of 1.32 Mpx (a 960 × 760 view is 0.73) and the frame's
// draw and raster take 5.0 instead of 8.8 ms (`node bench/viewer/raster-cost.mjs`).
//
// Which pixels a drawImage touches and which it overwrites whole depends on the rasterizer: with
// anti-aliased edges a tile's fractional edge blends into the pixel's previous value, so a
// pixel split between two tiles still shows what was under both; without (Chromium draws
// axis-aligned images without anti-aliasing) a pixel takes the tile's colour iff its centre
// lies inside the tile. `rasterModel` probes which one this browser does.

/** Doubt (device px) about where a rasterizer puts a tile edge: it computes edges in 32-bit
 * floats from the drawer's transform (centre plus or minus half the size), a few float ulps of
 * the tile's coordinates away from the doubles here (FLOAT_SLACK per unit of magnitude); and
 * without anti-aliasing a pixel centre this close to an edge may fall on either side
 * (CENTRE_SLACK). With anti-aliasing, a sliver of a pixel up to INVISIBLE wide changes no byte
 * (coverage is resolved in 1/256ths at best), which absorbs the float noise of ordinary tiles. */
const CENTRE_SLACK = 1 / 64;
const INVISIBLE = 1 / 1024;
const FLOAT_SLACK = 2 ** -20; // 8 × float32 epsilon

/**
 * The pixels `[from, to)` that a tile spanning device px `[a, b)` on one axis may touch
 * (`touch`) and surely overwrites whole (`cover`), with `slack` px of doubt about its edges.
 * `centres`: a pixel belongs to the tile iff its centre does (no anti-aliasing); else a pixel
 * is touched when the tile may span any of it, overwritten whole only when it surely spans all
 * of it (a negative `slack`: slivers that change no byte are ignored).
 */
export function pixelSpan(a, b, centres, slack = centres ? CENTRE_SLACK : -INVISIBLE) {
  const span = (from, to) => [from + 0, to + 0]; // + 0: no -0
  if (centres) {
    return {
      touch: span(Math.ceil(a - slack - 0.5), Math.floor(b + slack - 0.5) + 1),
      cover: span(Math.ceil(a + slack - 0.5), Math.floor(b - slack - 0.5) + 1),
    };
  }
  return {
    touch: span(Math.floor(a - slack), Math.ceil(b + slack)),
    cover: span(Math.ceil(a + slack), Math.floor(b - slack)),
  };
}

/**
 * A tile's pixel boxes `[x0, y0, x1, y1]` on the canvas: where drawing it may change pixels
 * (`touch`, clipped to the canvas) and where it replaces them whole (`cover`, null unless the
 * tile is loaded, opaque and drawn opaque). Null for a tile without a place on the canvas.
 * OpenSeadragon's canvas drawer draws a tile at `position` with `size` (CSS px, already one
 * pixel larger while smoothing is on) times the device pixel ratio. Chromium anti-aliases an
 * image less than a pixel wide or high even when it draws larger ones by pixel centres
 * (`centres` tells which applies).
 */
export function tileBoxes(tile, { width, height, ratio = 1, centres = false }) {
  const p = tile.position;
  const s = tile.size;
  if (!p || !s || !(s.x > 0 && s.y > 0)) return null;
  const [x0, y0, w, h] = [p.x * ratio, p.y * ratio, s.x * ratio, s.y * ratio];
  const byCentres = centres && w >= 1 && h >= 1;
  const axis = (a, size) => {
    const noise = (Math.abs(a + size / 2) + size / 2) * FLOAT_SLACK;
    return pixelSpan(a, a + size, byCentres, byCentres ? CENTRE_SLACK + noise : noise - INVISIBLE);
  };
  const x = axis(x0, w);
  const y = axis(y0, h);
  const touch = [Math.max(0, x.touch[0]), Math.max(0, y.touch[0]), Math.min(width, x.touch[1]), Math.min(height, y.touch[1])];
  const opaque = tile.loaded !== false && !tile.hasTransparency && !(tile.opacity < 1);
  const cover = opaque && x.cover[1] > x.cover[0] && y.cover[1] > y.cover[0] ? [x.cover[0], y.cover[0], x.cover[1], y.cover[1]] : null;
  return { touch, cover, centres: byCentres };
}

const empty = (r) => r[2] <= r[0] || r[3] <= r[1];
const area = (rects) => rects.reduce((a, r) => a + (r[2] - r[0]) * (r[3] - r[1]), 0);
const intersection = (a, b) => [Math.max(a[0], b[0]), Math.max(a[1], b[1]), Math.min(a[2], b[2]), Math.min(a[3], b[3])];
/** The non-empty parts of `rects` inside box `b`. */
const within = (rects, b) => rects.map((r) => intersection(r, b)).filter((r) => !empty(r));

/** `rects` (disjoint boxes) minus box `c`, as disjoint boxes. */
function subtract(rects, c) {
  const out = [];
  for (const r of rects) {
    if (c[0] >= r[2] || c[2] <= r[0] || c[1] >= r[3] || c[3] <= r[1]) {
      out.push(r);
      continue;
    }
    if (r[1] < c[1]) out.push([r[0], r[1], r[2], c[1]]);
    if (c[3] < r[3]) out.push([r[0], c[3], r[2], r[3]]);
    const y0 = Math.max(r[1], c[1]);
    const y1 = Math.min(r[3], c[3]);
    if (r[0] < c[0]) out.push([r[0], y0, c[0], y1]);
    if (c[2] < r[2]) out.push([c[2], y0, r[2], y1]);
  }
  return out;
}

/** A partly hidden tile is drawn clipped to what shows of it when that spares at least this
 * share of its pixels and this many, in at most MAX_TRIM_BOXES boxes. */
const TRIM_SHARE = 1 / 4;
const TRIM_PIXELS = 4096;
const MAX_TRIM_BOXES = 16;

/**
 * The tiles of `tiles` (in drawing order) that drawing would not show: every canvas pixel the
 * tile may touch is overwritten whole by an opaque tile drawn after it (or it touches none).
 * And `trims`: partly hidden tiles, mapped to the boxes of what shows of them — drawing a tile
 * clipped to those changes no pixel of the frame either. `canvas`: { width, height } in device
 * px, `ratio` (device px per CSS px), `centres` (see `rasterModel`). `clips` (optional) maps
 * tiles drawn clipped to the boxes they are drawn in (`addClips`). Tiles without a position
 * are always drawn whole. Also returns the pixel areas the tiles touch: all, hidden, and
 * trimmed off.
 */
export function hiddenTiles(tiles, canvas, clips = null) {
  const parts = tiles.map((t) => {
    const b = tileBoxes(t, canvas);
    if (!b) return null;
    const clip = clips && clips.get(t);
    const touch = empty(b.touch) ? [] : [b.touch];
    const cover = b.cover ? [b.cover] : [];
    return clip ? { touch: clip.flatMap((c) => within(touch, c)), cover: clip.flatMap((c) => within(cover, c)) } : { touch, cover };
  });
  const hidden = new Set();
  const trims = new Map();
  let total = 0;
  let hiddenArea = 0;
  let trimmedArea = 0;
  for (let i = 0; i < tiles.length; i++) {
    if (!parts[i]) continue;
    const size = area(parts[i].touch);
    total += size;
    let rest = parts[i].touch;
    for (let j = i + 1; j < tiles.length && rest.length; j++) {
      if (parts[j]) for (const c of parts[j].cover) rest = subtract(rest, c);
    }
    if (rest.length === 0) {
      hidden.add(tiles[i]);
      hiddenArea += size;
      continue;
    }
    const spared = size - area(rest);
    if (spared >= TRIM_PIXELS && spared >= TRIM_SHARE * size && rest.length <= MAX_TRIM_BOXES) {
      trims.set(tiles[i], rest);
      trimmedArea += spared;
    }
  }
  return { hidden, trims, area: total, hiddenArea, trimmedArea };
}

/**
 * Where to draw each tile of `add` on top of a canvas showing `prev` so that the canvas then
 * shows what drawing all of `next` would: a full redraw draws an old tile that `next` lists
 * after a new one over it where they overlap (while smoothing, OpenSeadragon enlarges every
 * tile by a pixel, so neighbours of one level overlap, and tiles arrive centre first while
 * `next` lists them column by column). Such a new tile is drawn outside the pixels the old
 * one overwrites. Returns a Map from the clipped tiles to the boxes they may be drawn in (the
 * others are drawn whole), or null when no clip is exact: without drawing by pixel centres
 * (`canvas.centres`; a shared pixel blends both tiles), for a tile less than a pixel wide or
 * high, or where the old tile's edge lies too close to pixel centres to know which pixels it
 * overwrites.
 */
export function addClips(prev, add, next, canvas) {
  const index = new Map(next.map((t, i) => [t, i]));
  const clips = new Map();
  for (const t of add) {
    const later = prev.filter((u) => index.get(u) > index.get(t));
    if (later.length === 0) continue;
    const bt = tileBoxes(t, canvas);
    if (!bt) return null;
    if (empty(bt.touch)) continue;
    let rects = [bt.touch];
    for (const u of later) {
      const bu = tileBoxes(u, canvas);
      if (!bu) return null;
      const shared = intersection(bt.touch, bu.touch);
      if (empty(shared)) continue;
      if (!bt.centres || !bu.centres || !bu.cover || subtract([shared], bu.cover).length) return null;
      rects = subtract(rects, bu.cover);
    }
    if (rects.length !== 1 || rects[0] !== bt.touch) clips.set(t, rects);
  }
  return clips;
}

/**
 * Whether this browser's 2D canvas draws an axis-aligned image without anti-aliasing, so that
 * a pixel takes the image's colour iff its centre lies inside the destination rectangle (true
 * in Chromium), judged by drawing a white image at fractional bounds onto black. False when
 * unsure: then only pixels a tile spans whole count as covered.
 */
export function rasterModel(doc = globalThis.document) {
  try {
    const canvas = doc.createElement('canvas');
    canvas.width = 4;
    canvas.height = 4;
    const g = canvas.getContext('2d', { willReadFrequently: true });
    const white = doc.createElement('canvas');
    white.width = 2;
    white.height = 2;
    const w = white.getContext('2d');
    w.fillStyle = '#fff';
    w.fillRect(0, 0, 2, 2);
    g.fillStyle = '#000';
    g.fillRect(0, 0, 4, 4);
    // Spans 0.3 … 2.7 on both axes: centres 0.5, 1.5, 2.5 inside, 3.5 outside.
    g.drawImage(white, 0, 0, 2, 2, 0.3, 0.3, 2.4, 2.4);
    const d = g.getImageData(0, 0, 4, 4).data;
    const at = (x, y) => d[(y * 4 + x) * 4];
    return at(0, 0) === 255 && at(2, 2) === 255 && at(1, 0) === 255 && at(3, 3) === 0 && at(3, 0) === 0 && at(0, 3) === 0;
  } catch {
    return false;
  }
}
