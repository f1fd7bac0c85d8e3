// The per-model WebAssembly modules as scripts/build-wasm writes them: the models are the
// `model-*` features of wasm/Cargo.toml (the list that script builds), each module at
// target/wasm-modules/<moduleFile(model)>.
import { readFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { moduleFile } from '../../client-web/src/shared/vtex-synth.js';

export const ROOT = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');

/** Every model a module is built for, in the order of wasm/Cargo.toml. */
export const MODELS = [...readFileSync(join(ROOT, 'wasm', 'Cargo.toml'), 'utf8').matchAll(/^model-([a-z-]+) = /gm)].map((m) => m[1]);

/** Where the module of `model` is built. */
export const modulePath = (model) => join(ROOT, 'target', 'wasm-modules', moduleFile(model));
