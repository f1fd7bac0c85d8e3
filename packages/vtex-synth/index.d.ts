// Types of vtex-synth's public API (index.js, node.js and the wrapper vtex-synth.js they export).
// The WebAssembly and fetch types come from the DOM library (a page, a Worker) or @types/node.

/** How an animated texture moves: a render's `frame` counts ticks at `fps`. */
export interface Animation {
  fps: number;
  /** Frames after which the animation repeats exactly; 0 when it never does. */
  period_frames: number;
}

/**
 * A texture as vtex describes it: the answer to `GET /api/v1/textures/{id}`, and
 * `SynthTexture.info` (the same value for the same encoding and tile size).
 */
export interface TextureInfo {
  /** The BLAKE3 of the encoding's bytes, in hex: the server's texture id. */
  id: string;
  name: string;
  /** The model that renders it: pick its module with `loadModule(info.model)`. */
  model: string;
  width: number;
  height: number;
  /** Levels served as tiles: level 0 is full size, each next one half as large. */
  levels: number;
  tile_size: number;
  /** Tiles a side of a metatile. */
  metatile: number;
  encoding_bytes: number;
  /** Bytes of the explicit 24-bit level 0 the encoding stands for. */
  explicit_bytes: number;
  wraps: boolean;
  /** `torus`: periodic with its size; `plane`: defined everywhere, served over its extent. */
  domain: 'torus' | 'plane';
  animated: boolean;
  animation: Animation | null;
  /** The parameters it was created with. */
  params: Record<string, unknown>;
  /** The parameters its model derived where they were not given. */
  derived: Record<string, unknown>;
}

/** A region of a level in its pixels; coordinates may be negative or past the texture's size. */
export interface Region {
  level: number;
  x: number;
  y: number;
  width: number;
  height: number;
  /** The animation frame; 0 by default. */
  frame?: number;
}

/** A tile as the server cuts it: RGBA8 rows, `width × height × 4` bytes (edge tiles are clipped). */
export interface Tile {
  width: number;
  height: number;
  data: Uint8Array<ArrayBuffer>;
}

/** Why the module refused a call (its message names the problem), or why it stopped. */
export class SynthError extends Error {
  constructor(message: string);
  name: 'SynthError';
}

/** The file name of the module that renders textures of `model`: `vtex_synth_<model>.wasm`. */
export function moduleFile(model: string): string;

/**
 * The URL of the module of `model`: in this package's `wasm/` folder, or under `base` where an
 * application serves those files itself. Throws a SynthError if `model` is not a model's name.
 */
export function moduleUrl(model: string, base?: string | URL): URL;

/**
 * Fetches (in Node: reads) and compiles the module of `model`. The compiled module can be
 * instantiated several times, or posted to Workers.
 */
export function loadModule(model: string, base?: string | URL): Promise<WebAssembly.Module>;

/** Instantiates a module from its bytes or compiled. */
export function instantiate(source: BufferSource | WebAssembly.Module): Promise<Synth>;

/** One instance of a module: the textures opened in it share its memory. */
export class Synth {
  constructor(instance: WebAssembly.Instance);
  /** Set once a call trapped (a bug in the module): the instance then refuses every call. */
  readonly failure: string | null;
  /**
   * Opens an encoding (`GET /api/v1/textures/{id}/encoding`) to be cut into tiles of `tileSize`
   * (from 1 to 65,535, as the server's `tile_size`). Throws a SynthError naming what is wrong:
   * a truncated, corrupted or unknown encoding, another model's.
   */
  open(encoding: Uint8Array | ArrayBuffer, tileSize: number): SynthTexture;
}

/** A texture open in a Synth. */
export class SynthTexture {
  private constructor();
  /** The server's info for this encoding and tile size. */
  readonly info: TextureInfo;
  /** The RGBA8 rows of `region` (at most 16 Mpx): the server's pixels exactly. */
  render(region: Region): Uint8Array<ArrayBuffer>;
  /** Tile (tx, ty) of `level` at `frame`: the server's tile exactly. */
  renderTile(level: number, tx: number, ty: number, frame?: number): Tile;
  /** Frees the texture in the module; later calls throw a SynthError. */
  close(): void;
}
