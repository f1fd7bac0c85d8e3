// What the viewer opens: the texture a link names, else a showcase at a zoom where its structure
// shows. Zoomed fully out, a 100k texture is one tile of its mean colour, a flat square that
// says nothing of what vtex does.

import { findTexture } from './texture-lookup.js';

/** The showcase: the flagship demo, the chaos mosaic of pebbles, 100,000² from a 61 KB encoding. */
export const SHOWCASE = 'Pebbles — chaos mosaic 100k';

/**
 * Zoom (screen px per level-0 px) a texture opens at by default: half resolution, where the
 * showcase's stones and the mosaic's blocks show (level 1 drawn at 1:1).
 */
export const FIRST_ZOOM = 0.5;

/**
 * The texture to open among `textures` for the link's `view` (view-url.js parseView), the view
 * to open it at, and the message to show (or '' when the link is fine):
 * - the texture the link names, at the link's view (the whole texture when it gives none, as
 *   when a texture is picked);
 * - else the showcase when the server has it, else the largest texture, at its centre and the
 *   FIRST_ZOOM, unless the link gives a view; a link naming no texture says which one
 *   is shown instead.
 */
export function firstView(textures, view) {
  const named = findTexture(textures, view.texture);
  if (named) return { info: named, view, message: '' };
  const info =
    textures.find((t) => t.name === SHOWCASE) ||
    textures.reduce((a, b) => (b.width * b.height > a.width * a.height ? b : a));
  const opened = { zoom: FIRST_ZOOM, x: info.width / 2, y: info.height / 2, ...view, texture: info.id };
  const message = view.texture
    ? `No texture "${view.texture}" on this server (or more than one starts so); showing ${info.name}.`
    : '';
  return { info, view: opened, message };
}
