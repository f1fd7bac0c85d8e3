// The panel that creates a texture: pick a model (`GET /api/v1/models`), edit its parameters
// in a form generated from its JSON Schema (schema-form.js; or as JSON), give its input images
// (the model's example images unless a file is chosen) and post it all as the multipart upload
// `POST /api/v1/textures` takes. The server's answer is shown as it is: the new texture opens,
// and a refusal (a JSON error naming the problem) is shown in the panel.

import { FormError, createForm, parseJson, stringifyJson } from './schema-form.js';
import { formatBytes } from './stats.js';
import { fetchOk, getJson } from '../shared/http.js';

const $ = (id) => document.getElementById(id);

/**
 * Wires the panel (index.html `#create-panel`, opened by `#create-toggle`). `onCreated(info)`
 * is awaited with the server's info of the texture made.
 */
export function setupCreatePanel({ onCreated }) {
  const panel = $('create-panel');
  const toggle = $('create-toggle');
  const state = { models: null, model: null, params: null, json: null, inputs: [], busy: false };

  toggle.addEventListener('click', async () => {
    panel.hidden = !panel.hidden;
    toggle.setAttribute('aria-expanded', String(!panel.hidden));
    if (!panel.hidden && !state.models) await loadModels();
  });

  async function loadModels() {
    status('Loading the models…');
    try {
      state.models = (await getJson('api/v1/models')).models;
    } catch (e) {
      status(`Could not list the models (GET /api/v1/models): ${e.message}`, 'error');
      return;
    }
    const picker = $('create-model');
    picker.replaceChildren(...state.models.map((m) => new Option(`${m.title} (${m.id})`, m.id)));
    picker.disabled = false;
    status('');
    showModel(state.models[0]);
  }

  $('create-model').addEventListener('change', (e) => {
    const model = state.models.find((m) => m.id === e.target.value);
    if (model) showModel(model);
  });

  function showModel(model) {
    state.model = model;
    $('create-model').value = model.id;
    $('create-about').textContent = `${model.summary} — ${model.paper}`;
    $('create-name').value = '';
    $('create-name').placeholder = `${model.title} (the texture's name)`;
    showParams(model.example ? model.example.params : {});
    showInputs(model);
    status('');
  }

  /** The parameters as a form (or, in JSON mode, a text area) holding `value`. */
  function showParams(value) {
    const holder = $('create-params');
    if (state.json !== null) {
      state.json = stringifyJson(value, 2);
      const area = document.createElement('textarea');
      area.id = 'create-params-json';
      area.className = 'schema-json';
      area.spellcheck = false;
      area.rows = 16;
      area.value = state.json;
      area.setAttribute('aria-label', 'params as JSON');
      holder.replaceChildren(area);
      state.params = null;
      return;
    }
    state.params = createForm(state.model.params_schema, value);
    holder.replaceChildren(state.params.element);
  }

  /** The parameters entered: a JSON value, or a FormError naming what is wrong. */
  function readParams() {
    if (state.params) return state.params.read();
    try {
      return parseJson($('create-params-json').value);
    } catch (e) {
      throw new FormError(`params: not JSON (${e.message})`);
    }
  }

  $('create-params-mode').addEventListener('click', () => {
    let value;
    try {
      value = readParams();
    } catch (e) {
      if (e instanceof FormError) return status(e.message, 'error');
      throw e;
    }
    state.json = state.json === null ? '' : null;
    $('create-params-mode').textContent = state.json === null ? 'Edit as JSON' : 'Edit as form';
    showParams(value);
  });

  /**
   * A row per input image: the model's named inputs, the example's other inputs (a model
   * whose inputs are named by its parameters: `*`), and rows added by hand for such a model.
   */
  function showInputs(model) {
    const list = $('create-inputs');
    list.replaceChildren();
    state.inputs = [];
    const examples = (model.example && model.example.inputs) || {};
    for (const input of model.inputs.filter((i) => i.name !== '*')) addInputRow(input.name, input, examples[input.name]);
    const named = new Set(model.inputs.map((i) => i.name));
    for (const [name, example] of Object.entries(examples)) if (!named.has(name)) addInputRow(name, null, example);
    const any = model.inputs.find((i) => i.name === '*');
    $('create-add-input').hidden = !any;
    $('create-add-input').title = any ? any.what : '';
    $('create-inputs-section').hidden = model.inputs.length === 0;
  }

  function addInputRow(name, input, example) {
    const row = document.createElement('div');
    row.className = 'create-input';
    const nameField = document.createElement('input');
    nameField.type = 'text';
    nameField.value = name;
    nameField.readOnly = Boolean(input || example);
    nameField.placeholder = 'input name (as the parameters name it)';
    nameField.setAttribute('aria-label', 'input name');
    const file = document.createElement('input');
    file.type = 'file';
    file.accept = 'image/png,image/*';
    file.setAttribute('aria-label', `input ${name || 'image'}`);
    const note = document.createElement('div');
    note.className = 'dim';
    const what = input ? `${input.required ? 'required' : 'optional'}: ${input.what}` : '';
    note.textContent = [what, example ? `Without a file, the example's: ${example.what}` : ''].filter(Boolean).join('. ');
    row.append(nameField, file);
    if (example) {
      const thumb = document.createElement('img');
      thumb.src = example.href;
      thumb.alt = `example ${name}`;
      thumb.className = 'create-thumb';
      row.append(thumb);
    }
    row.append(note);
    $('create-inputs').append(row);
    const entry = {
      name: () => nameField.value.trim(),
      file: () => file.files[0] || null,
      example: example || null,
    };
    state.inputs.push(entry);
  }

  $('create-add-input').addEventListener('click', () => addInputRow('', null, null));

  $('create-form').addEventListener('submit', async (e) => {
    e.preventDefault();
    if (state.busy || !state.model) return;
    state.busy = true;
    $('create-submit').disabled = true;
    try {
      await submit();
    } finally {
      state.busy = false;
      $('create-submit').disabled = false;
    }
  });

  async function submit() {
    status('');
    for (const f of $('create-params').querySelectorAll('.refused')) f.classList.remove('refused');
    let params;
    try {
      params = readParams();
    } catch (e) {
      if (e instanceof FormError) return status(e.message, 'error');
      throw e;
    }
    const form = new FormData();
    form.append('model', state.model.id);
    form.append('name', $('create-name').value.trim() || state.model.title);
    form.append('params', stringifyJson(params === undefined ? {} : params));
    status('Creating…');
    try {
      for (const input of state.inputs) {
        const image = input.file() || (input.example ? await fetchImage(input.example.href) : null);
        if (image && input.name()) form.append(input.name(), image, input.file() ? input.file().name : `${input.name()}.png`);
      }
    } catch (e) {
      return status(`Could not read an input image: ${e.message}`, 'error');
    }
    const token = $('create-token').value.trim();
    let response;
    let body = null;
    try {
      response = await fetch('api/v1/textures', {
        method: 'POST',
        body: form,
        headers: token ? { Authorization: `Bearer ${token}` } : {},
      });
      body = await response.json().catch(() => null);
    } catch (e) {
      return status(`The upload failed: ${e.message}`, 'error');
    }
    if (!response.ok) return refused(response.status, body);
    status(`${response.status === 201 ? 'Created' : 'Already stored'}: ${body.name} — ${body.width.toLocaleString('en-US')} × ${body.height.toLocaleString('en-US')}, encoding ${formatBytes(body.encoding_bytes)}.`, 'ok');
    await onCreated(body);
  }

  /** Shows the server's refusal; a write token asked for opens its field. */
  function refused(code, body) {
    const why = body && body.error ? body.error : 'no reason given';
    if (code === 401) {
      $('create-token-box').open = true;
      $('create-token').focus();
      status(`The server needs its write token (HTTP 401): ${why}`, 'error');
    } else if (code === 403) {
      status(`The server refuses writes (HTTP 403): ${why}`, 'error');
    } else {
      status(`The server refused it (HTTP ${code}): ${why}`, 'error');
      markNamedFields(why);
    }
  }

  /**
   * Marks the fields a refusal names (the models say "invalid parameter `c_lambda/c_mu`" or
   * "`layers[2].weight`", paths as in the parameters' JSON) and brings the first into view.
   */
  function markNamedFields(why) {
    const named = /invalid parameter `([^`]+)`/.exec(why);
    if (!named || !state.params) return;
    const paths = named[1].split('/').map((p) => `params.${p}`);
    const fields = [...$('create-params').querySelectorAll('[data-path]')].filter((f) => paths.includes(f.dataset.path));
    for (const f of fields) f.classList.add('refused');
    if (fields.length) fields[0].scrollIntoView({ block: 'center' });
  }

  function status(message, kind = '') {
    const box = $('create-status');
    box.textContent = message;
    box.className = kind;
    box.hidden = !message;
  }
}

async function fetchImage(href) {
  return (await fetchOk(href, 'an example image')).blob();
}
