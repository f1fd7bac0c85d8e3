// The 3D world's scene (world.html): a courtyard whose floor is a chaos mosaic, walls a
// cascade texture and a message board a patterns texture, each a virtual texture; and the
// walk through it that the scripted camera follows. World units are level-0 texels of the floor
// (a texel a centimetre: the courtyard is 30 m a side, its walls 7 m high, the eye at 1.6 m).
// Pure, tested in Node.

/** The courtyard's centre on the floor texture (the middle of a 100k texture), its half side and wall height. */
export const CENTRE = 50_000;
export const HALF = 1500;
export const WALL_HEIGHT = 700;
/** Eye height and field of view (degrees, vertical) of the walk. */
export const EYE = 160;
export const FOV = 60;

/**
 * What each surface shows: a texture of `model`, by preference the demo named `prefer`, else the
 * first of that model whose page table fits (vt-pages.js pyramid); `param` overrides it in the URL
 * (id, name or id prefix).
 */
export const SURFACES = [
  { role: 'floor', param: 'floor', model: 'chaos-mosaic', prefer: 'Pebbles — chaos mosaic 100k' },
  { role: 'walls', param: 'walls', model: 'cascade', prefer: 'Cascade E — marble veins' },
  { role: 'board', param: 'board', model: 'patterns', prefer: 'Patterns: blinking LED message board (12288×1536)' },
];

/** Where on the wall texture the walls' texels start (a cascade texture is a plane: its middle). */
const WALL_TEXELS = [40_000, 40_000];
/** The board: on the north wall's inner face, 20 units in front of it, its bottom edge and height. */
const BOARD = { inset: 20, bottom: 260, height: 300 };

/**
 * The rectangles of the scene for textures of sizes `sizes` ({ walls: { width, height }, board: …
 * }): [{ role, corners: [[x, y, z] × 4], texels: [[u, v] × 4] }]. The four walls run round the
 * courtyard as one strip of the wall texture, 1 texel a unit, its rows top down; the board shows
 * its whole texture, as wide as its height allows.
 */
export function rectangles(sizes) {
  const [x0, x1, y0, y1] = [CENTRE - HALF, CENTRE + HALF, CENTRE - HALF, CENTRE + HALF];
  const side = 2 * HALF;
  // Counter-clockwise seen from above: north (y0), east (x1), south (y1), west (x0).
  const ends = [
    [[x0, y0], [x1, y0]],
    [[x1, y0], [x1, y1]],
    [[x1, y1], [x0, y1]],
    [[x0, y1], [x0, y0]],
  ];
  const [u0, v0] = WALL_TEXELS;
  const walls = ends.map(([a, b], i) => ({
    role: 'walls',
    corners: [[...a, 0], [...b, 0], [...b, WALL_HEIGHT], [...a, WALL_HEIGHT]],
    texels: [
      [u0 + i * side, v0 + WALL_HEIGHT],
      [u0 + (i + 1) * side, v0 + WALL_HEIGHT],
      [u0 + (i + 1) * side, v0],
      [u0 + i * side, v0],
    ],
  }));
  const { width, height } = sizes.board;
  const w = Math.min(side - 200, (BOARD.height * width) / height);
  const [bx0, bx1, by, z0, z1] = [CENTRE - w / 2, CENTRE + w / 2, y0 + BOARD.inset, BOARD.bottom, BOARD.bottom + BOARD.height];
  const board = {
    role: 'board',
    corners: [[bx0, by, z0], [bx1, by, z0], [bx1, by, z1], [bx0, by, z1]],
    texels: [[0, height], [width, height], [width, 0], [0, 0]],
  };
  return [...walls, board];
}

/**
 * The scripted walk at step `i` of `steps`: once round a circle of 900 units about the centre,
 * looking ahead and a little inwards, the gaze sweeping from the floor near the feet up to the
 * walls and the board. Camera: { x, y, height, yaw, pitch, fov } (yaw 0 looks towards −y, pitch down).
 */
export function walk(i, steps) {
  const a = (2 * Math.PI * i) / steps;
  const x = CENTRE + 900 * Math.sin(a);
  const y = CENTRE + 900 * Math.cos(a);
  // The direction of travel (cos a, −sin a) is yaw 90° − a; the centre lies 90° to its left.
  const heading = 90 - (a * 180) / Math.PI;
  return { x, y, height: EYE, yaw: heading - 30, pitch: 12 + 10 * Math.sin(3 * a), fov: FOV };
}
