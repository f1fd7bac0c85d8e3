// vtex-synth for browsers and bundlers (Node takes node.js, which reads the modules from disk):
// the wrapper of the WebAssembly modules, and where this package keeps each model's module.
import { moduleFile, SynthError } from './vtex-synth.js';

export { instantiate, moduleFile, Synth, SynthError, SynthTexture } from './vtex-synth.js';

/**
 * The URL of the module that renders textures of `model` (a texture info's `model`): in this
 * package's wasm/ folder, or under `base` where an application serves those files itself.
 */
export function moduleUrl(model, base = new URL('./wasm/', import.meta.url)) {
  // A model comes from a server's answer: a name, never a path.
  if (typeof model !== 'string' || !/^[a-z0-9-]{1,64}$/.test(model)) throw new SynthError(`not a model name: ${JSON.stringify(model)}`);
  return new URL(moduleFile(model), base);
}

/** Fetches and compiles the module of `model` (see moduleUrl); instantiate it, or post it to Workers. */
export async function loadModule(model, base) {
  const url = moduleUrl(model, base);
  const response = await fetch(url);
  if (!response.ok) throw new SynthError(`no module for model \`${model}\`: ${url} answered HTTP ${response.status}`);
  return WebAssembly.compile(await response.arrayBuffer());
}
