// The view in the URL: `?texture=<id or name>&zoom=<screen px per level-0 px>&x=<cx>&y=<cy>[&frame=N][&format=F][&detail=D][&synth=client]`.
// x and y are the view centre in level-0 pixels, so a link means the same place at any window size.

import { DETAIL } from './pyramid.js';

/** Tile formats the server offers. */
export const FORMATS = ['png', 'webp', 'jpg', 'rgba'];

/** Parses a query string into a view; fields that are absent or malformed are left out. */
export function parseView(search) {
  const q = new URLSearchParams(search);
  const view = {};
  const texture = q.get('texture');
  if (texture) view.texture = texture;
  const num = (k) => {
    const s = q.get(k);
    if (s === null || s.trim() === '') return undefined;
    const v = Number(s);
    return Number.isFinite(v) ? v : undefined;
  };
  const zoom = num('zoom');
  if (zoom !== undefined && zoom > 0) view.zoom = zoom;
  const x = num('x');
  const y = num('y');
  if (x !== undefined && y !== undefined) {
    view.x = x;
    view.y = y;
  }
  const frame = num('frame');
  if (frame !== undefined && Number.isInteger(frame) && frame >= 0 && frame < 2 ** 32) view.frame = frame;
  const format = q.get('format');
  if (FORMATS.includes(format)) view.format = format;
  const detail = q.get('detail');
  if (Object.hasOwn(DETAIL, detail)) view.detail = detail;
  if (q.get('synth') === 'client') view.synth = 'client';
  return view;
}

/** Formats a view as a query string (with the leading `?`). */
export function formatView(view) {
  const q = new URLSearchParams();
  if (view.texture) q.set('texture', view.texture);
  // Precise enough that a restored view lands within 1/1000 of a screen pixel of the original.
  if (view.zoom > 0) q.set('zoom', String(Number(view.zoom.toPrecision(10))));
  if (Number.isFinite(view.x) && Number.isFinite(view.y)) {
    q.set('x', String(Math.round(view.x * 1000) / 1000));
    q.set('y', String(Math.round(view.y * 1000) / 1000));
  }
  if (view.frame > 0) q.set('frame', String(view.frame));
  if (view.format) q.set('format', view.format);
  if (view.detail) q.set('detail', view.detail);
  if (view.synth) q.set('synth', view.synth);
  return `?${q}`;
}
