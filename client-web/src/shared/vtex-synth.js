// vtex-synth in WebAssembly (the crate `wasm/`, built once per model as vtex_synth_<model>.wasm,
// each holding only the renderer of its model: moduleFile): open an encoding bundle, read its
// info (the server's), render regions and tiles as RGBA — the server's bytes exactly. The
// module's raw ABI (wasm/src/api.rs) takes numbers and two buffers it owns; this wrapper turns
// it into objects and exceptions. It runs in a page, a Worker and Node alike, and is the API of
// the npm package vtex-synth too (packages/vtex-synth, whose index.d.ts types it).

/** Why the module refused a call (its message names the problem), or why it stopped. */
export class SynthError extends Error {
  constructor(message) {
    super(message);
    this.name = 'SynthError';
  }
}

/**
 * The file name of the module that renders textures of `model` (the `model` of a texture's info),
 * as `scripts/build-wasm` names it and the viewer's build ships it.
 */
export function moduleFile(model) {
  return `vtex_synth_${model}.wasm`;
}

/**
 * Instantiates the module from its bytes or a compiled WebAssembly.Module (one compiled module
 * may be posted to several Workers and instantiated in each).
 */
export async function instantiate(source) {
  const result = await WebAssembly.instantiate(source, {});
  return new Synth(result.instance || result);
}

const decoder = new TextDecoder();

/** One instance of the module: the textures opened in it share its memory. */
export class Synth {
  constructor(instance) {
    this.exports = instance.exports;
    /** Set once a call trapped: the instance may be inconsistent and is not used again. */
    this.failure = null;
    this.exports.vtex_init();
  }

  /**
   * Opens bundle `bytes` (a Uint8Array or ArrayBuffer) to be cut into tiles of `tileSize`, as the
   * server's are; throws a SynthError naming what is wrong.
   */
  open(bytes, tileSize) {
    const data = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
    const handle = this.call(() => {
      const ptr = this.exports.vtex_input(data.length);
      new Uint8Array(this.exports.memory.buffer, ptr, data.length).set(data);
      return this.exports.vtex_open(tileSize >>> 0);
    });
    if (handle === 0) throw new SynthError(this.outputText());
    return new SynthTexture(this, handle, JSON.parse(this.outputText()));
  }

  /** Runs `f` (calls into the module), turning a trap into a SynthError with the panic's message. */
  call(f) {
    if (this.failure) throw new SynthError(`the synthesis module stopped after an earlier failure: ${this.failure}`);
    try {
      return f();
    } catch (e) {
      if (!(e instanceof WebAssembly.RuntimeError)) throw e;
      const len = this.exports.vtex_panic_message_len();
      const panic = len ? decoder.decode(new Uint8Array(this.exports.memory.buffer, this.exports.vtex_panic_message(), len)) : '';
      this.failure = panic || e.message;
      throw new SynthError(`the synthesis module failed: ${this.failure}`);
    }
  }

  /** The output buffer of the last call, copied out of the module's memory. */
  outputBytes() {
    const ptr = this.exports.vtex_output();
    const len = this.exports.vtex_output_len();
    return new Uint8Array(this.exports.memory.buffer, ptr, len).slice();
  }

  outputText() {
    return decoder.decode(this.outputBytes());
  }
}

/**
 * A texture open in a Synth. `info` is the server's texture info (wire/src/info.rs) for the same
 * bytes and tile size: `id` is the bundle's content id, the server's texture id, and `levels`
 * are those served as tiles.
 */
export class SynthTexture {
  constructor(synth, handle, info) {
    this.synth = synth;
    this.handle = handle;
    this.info = info;
  }

  /** RGBA8 rows of the region of `level` at (x, y), `width` × `height`, at `frame`. */
  render({ level, x, y, width, height, frame = 0 }) {
    const ok = this.synth.call(() => this.synth.exports.vtex_render(this.live(), level >>> 0, x, y, width >>> 0, height >>> 0, frame >>> 0));
    if (ok === 0) throw new SynthError(this.synth.outputText());
    return this.synth.outputBytes();
  }

  /** Tile (tx, ty) of `level` at `frame` as the server cuts tiles of `info.tile_size`: { width, height, data }. */
  renderTile(level, tx, ty, frame = 0) {
    const size = this.synth.call(() => this.synth.exports.vtex_render_tile(this.live(), level >>> 0, tx >>> 0, ty >>> 0, frame >>> 0));
    if (size === 0) throw new SynthError(this.synth.outputText());
    return { width: size >>> 16, height: size & 0xffff, data: this.synth.outputBytes() };
  }

  /** Frees the texture in the module; the object cannot be used afterwards. */
  close() {
    if (this.handle === 0) return;
    const handle = this.handle;
    this.handle = 0;
    this.synth.call(() => this.synth.exports.vtex_close(handle));
  }

  live() {
    if (this.handle === 0) throw new SynthError(`texture ${this.info.name} is closed`);
    return this.handle;
  }
}
