// Where the viewer opens a texture: at the link's view when it gives a zoom, else where the
// texture's structure shows. Zoomed fully out, a 100k texture is one tile of its mean colour,
// a flat square that says nothing of what vtex does. The first texture opened, one picked in
// the list and one just created all open through `openingView`.

import { findTexture } from '../shared/texture-lookup.js';

/** The showcase: the flagship demo, the chaos mosaic of pebbles, 100,000² from a 61 KB encoding. */
export const SHOWCASE = 'Pebbles — chaos mosaic 100k';

/**
 * Zoom (screen px per level-0 px) a texture opens at by default: half resolution, where the
 * showcase's stones and the mosaic's blocks show (level 1 drawn at 1:1).
 */
export const FIRST_ZOOM = 0.5;

/**
 * The view `info` opens at given `view` (view-url.js parseView: a link's, or {} when the
 * texture is picked): the link's when it gives a zoom; else its centre at FIRST_ZOOM, or at
 * `fit` (the zoom that fits the whole texture on the screen) when that is larger, since then
 * the whole texture shows at least as much. Fields of `view` besides the place (frame,
 * format…) are kept.
 */
export function openingView(info, view = {}, fit = 0) {
  if (view.zoom > 0) return { ...view, texture: info.id };
  return { x: info.width / 2, y: info.height / 2, ...view, zoom: Math.max(FIRST_ZOOM, fit), texture: info.id };
}

/**
 * The texture to open among `textures` for the link's `view` (view-url.js parseView), the view
 * to open it at (openingView, with `fit` computed by `fitOf(info)`), and the message to show
 * ('' when the link is fine): the texture the link names; else the showcase when the server
 * has it, else the largest texture; a link naming no texture says which one is shown instead.
 */
export function firstView(textures, view, fitOf = () => 0) {
  const named = findTexture(textures, view.texture);
  if (named) return { info: named, view: openingView(named, view, fitOf(named)), message: '' };
  const info =
    textures.find((t) => t.name === SHOWCASE) ||
    textures.reduce((a, b) => (b.width * b.height > a.width * a.height ? b : a));
  const message = view.texture
    ? `No texture "${view.texture}" on this server (or more than one starts so); showing ${info.name}.`
    : '';
  return { info, view: openingView(info, view, fitOf(info)), message };
}
