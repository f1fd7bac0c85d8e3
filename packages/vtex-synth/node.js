// vtex-synth for Node: as index.js, but loadModule reads a module from disk (Node's fetch takes
// no file: URL).
import { readFile } from 'node:fs/promises';
import { loadModule as fetchModule, moduleUrl, SynthError } from './index.js';

export * from './index.js';

/** Reads (a file: URL, as by default) or fetches and compiles the module of `model` (see moduleUrl). */
export async function loadModule(model, base) {
  const url = moduleUrl(model, base);
  if (url.protocol !== 'file:') return fetchModule(model, base);
  let bytes;
  try {
    bytes = await readFile(url);
  } catch (e) {
    throw new SynthError(`no module for model \`${model}\`: ${e.code === 'ENOENT' ? `${url} does not exist` : e.message}`);
  }
  return WebAssembly.compile(bytes);
}
