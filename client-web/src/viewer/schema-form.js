// A form generated from a JSON Schema: the subset the models' parameter schemas use (schemars,
// draft 2020-12). Numbers and integers (with their bounds), strings, booleans, enumerations
// (`enum`, or `oneOf` of `const`s), objects, optional values (`anyOf [X, null]`, nullable
// types), unions tagged by a `const` property (`oneOf` of objects sharing e.g. `kind`), short
// fixed-length number arrays and lists of objects each get a field; anything else (maps by
// name, unions of unrelated types, variable-length number lists) a JSON field.
//
// A field left empty is left out of the value, so the model's default applies. Integers past
// 2^53 (seeds are u64) stay exact: they are read as BigInt and written back digit for digit.

/** A field the user filled in wrongly, named by its path in the parameters. */
export class FormError extends Error {}

/** `schema` with its `$ref` (to `#/$defs/…` of `root`) followed, its own keywords kept over the target's. */
export function resolve(schema, root) {
  let s = schema === true || schema == null ? {} : schema;
  for (let hops = 0; s.$ref && hops < 32; hops++) {
    const name = s.$ref.replace(/^#\/\$defs\//, '');
    const target = root.$defs && root.$defs[name];
    if (!target) throw new Error(`schema reference ${s.$ref} not found`);
    const { $ref: _, ...own } = s;
    s = { ...target, ...own };
  }
  return s;
}

const typesOf = (s) => (Array.isArray(s.type) ? s.type : s.type ? [s.type] : []);
const isNull = (s) => typesOf(s).length === 1 && s.type === 'null';
const SCALARS = ['integer', 'number', 'string', 'boolean'];

/** The values of an enumeration ({ value, description }), or null when `s` is none. */
export function choices(s) {
  if (Array.isArray(s.enum)) return s.enum.filter((v) => v !== null).map((value) => ({ value, description: '' }));
  const branches = s.oneOf || s.anyOf;
  if (branches && branches.every((b) => 'const' in b)) return branches.map((b) => ({ value: b.const, description: b.description || '' }));
  return null;
}

/** The property every branch of `branches` fixes with a `const` (a union's tag), or null. */
export function unionTag(branches, root) {
  const objects = branches.map((b) => resolve(b, root));
  if (!objects.every((b) => b.properties)) return null;
  const first = Object.keys(objects[0].properties);
  return first.find((k) => objects.every((b) => b.properties[k] && 'const' in resolve(b.properties[k], root))) || null;
}

/**
 * What field `schema` gets: { kind, schema (resolved), inner (optional's) }; kind is one of
 * enum, boolean, integer, number, string, object, optional, union, tuple, list, json.
 * `nullable` means null is allowed (the field may be left out).
 */
export function classify(schema, root) {
  const s = resolve(schema, root);
  const types = typesOf(s);
  const nullable = types.includes('null');
  if (choices(s)) return { kind: 'enum', schema: s, nullable };
  const branches = s.anyOf || s.oneOf;
  if (branches) {
    const real = branches.filter((b) => !isNull(b));
    if (real.length === 1 && real.length < branches.length) return { kind: 'optional', schema: s, inner: real[0] };
    if (unionTag(real, root)) return { kind: 'union', schema: s, nullable: real.length < branches.length };
    return { kind: 'json', schema: s, nullable: true };
  }
  const base = types.filter((t) => t !== 'null');
  if (base.length !== 1) return { kind: 'json', schema: s, nullable: true };
  const [type] = base;
  if (SCALARS.includes(type)) return { kind: type, schema: s, nullable };
  if (type === 'object') {
    const additional = s.additionalProperties && s.additionalProperties !== true ? s.additionalProperties : null;
    if (s.properties && !additional) return nullable ? optionalOf(s) : { kind: 'object', schema: s, nullable };
    return { kind: 'json', schema: s, nullable: true };
  }
  if (type === 'array') {
    if (nullable) return optionalOf(s);
    const items = s.items && !s.prefixItems ? classify(s.items, root) : null;
    const numeric = items && (items.kind === 'number' || items.kind === 'integer') && !items.nullable;
    if (numeric && s.minItems === s.maxItems && s.minItems >= 1 && s.minItems <= 4) return { kind: 'tuple', schema: s, nullable };
    if (items && ['object', 'union'].includes(items.kind)) return { kind: 'list', schema: s, nullable };
  }
  return { kind: 'json', schema: s, nullable: true };
}

/** `s` as an optional field around the same schema without null. */
function optionalOf(s) {
  return { kind: 'optional', schema: s, inner: { ...s, type: typesOf(s).filter((t) => t !== 'null')[0] } };
}

/** Marks a long integer literal as a string for `parseJson`'s reviver. */
const BIG = '\u0000integer:';

/** Parses JSON keeping integers beyond 2^53 exact (as BigInt), so a u64 seed survives an edit. */
export function parseJson(text) {
  // Strings are matched whole (and kept), so only integer literals of 16 or more digits that
  // are tokens of their own are quoted, with a marker no JSON text can hold unescaped.
  const marked = text.replace(/"(?:[^"\\]|\\.)*"|(?<![\d.eE+-])-?\d{16,}(?![\d.eE])/g, (m) =>
    m[0] === '"' ? m : `"\\u0000integer:${m}"`,
  );
  return JSON.parse(marked, (key, value) => {
    if (typeof value !== 'string' || !value.startsWith(BIG)) return value;
    const digits = value.slice(BIG.length);
    return Number.isSafeInteger(Number(digits)) ? Number(digits) : BigInt(digits);
  });
}

/** JSON text of `value`, BigInts written as their digits; `indent` as JSON.stringify's. */
export function stringifyJson(value, indent) {
  const marks = [];
  const text = JSON.stringify(
    value,
    (key, v) => {
      if (typeof v !== 'bigint') return v;
      marks.push(v.toString());
      return `\u0000bigint${marks.length - 1}\u0000`;
    },
    indent,
  );
  // JSON.stringify writes the marker's NULs escaped.
  return text === undefined ? text : text.replace(/"\\u0000bigint(\d+)\\u0000"/g, (_, i) => marks[Number(i)]);
}

/** Reads an integer field's text: a Number, a BigInt past 2^53, or a FormError naming `path`. */
export function readInteger(text, path) {
  const t = text.trim();
  if (!/^-?\d+$/.test(t)) throw new FormError(`${path}: "${text}" is not an integer`);
  const n = Number(t);
  return Number.isSafeInteger(n) ? n : BigInt(t);
}

/** Reads a number field's text, or a FormError naming `path`. */
export function readNumber(text, path) {
  const n = Number(text.trim());
  if (text.trim() === '' || !Number.isFinite(n)) throw new FormError(`${path}: "${text}" is not a number`);
  return n;
}

/** Bounds of a JSON Schema integer `format` (schemars' uint8 … int64). */
const FORMAT_BOUNDS = {
  uint8: [0, 255],
  uint16: [0, 65535],
  uint32: [0, 4294967295],
  int8: [-128, 127],
  int16: [-32768, 32767],
  int32: [-2147483648, 2147483647],
};

/**
 * Builds the form of `schema` (the root of its `$defs`) holding `value`, in document `doc`.
 * Returns { element, read }: `read()` gives the value (fields left empty left out) or throws
 * a FormError naming the field.
 */
export function createForm(schema, value, doc = document) {
  const ctx = { root: schema, doc };
  return editor(schema, value, 'params', ctx, true);
}

function el(ctx, tag, props = {}, ...children) {
  const node = ctx.doc.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (v === undefined || v === null) continue;
    if (k === 'class') node.className = v;
    else if (k in node && k !== 'list') node[k] = v;
    else node.setAttribute(k, v);
  }
  node.append(...children);
  return node;
}

/** One field: { element, read }. `required`: the parent requires it (it is never left out). */
function editor(schema, value, path, ctx, required) {
  const c = classify(schema, ctx.root);
  const s = c.schema;
  const title = s.description || '';
  const make = {
    enum: enumEditor,
    boolean: booleanEditor,
    integer: numberEditor,
    number: numberEditor,
    string: stringEditor,
    object: objectEditor,
    optional: optionalEditor,
    union: unionEditor,
    tuple: tupleEditor,
    list: listEditor,
    json: jsonEditor,
  }[c.kind];
  const e = make(c, value, path, ctx, required);
  if (title && !e.element.title) e.element.title = title;
  e.element.dataset.path = path;
  return e;
}

function enumEditor(c, value, path, ctx, required) {
  const options = choices(c.schema);
  const select = el(ctx, 'select', { 'aria-label': path });
  const defaultValue = c.schema.default;
  if (!required || c.nullable) {
    const label = defaultValue === undefined || defaultValue === null ? '(not set)' : `(default: ${defaultValue})`;
    select.append(el(ctx, 'option', { value: '' }, label));
  }
  options.forEach((o, i) => select.append(el(ctx, 'option', { value: String(i), title: o.description }, String(o.value))));
  const at = options.findIndex((o) => o.value === value);
  select.value = at >= 0 ? String(at) : required && !c.nullable && options.length ? '0' : '';
  return { element: select, read: () => (select.value === '' ? undefined : options[Number(select.value)].value) };
}

function booleanEditor(c, value, path, ctx, required) {
  if (required && !c.nullable) {
    const box = el(ctx, 'input', { type: 'checkbox', checked: value === true, 'aria-label': path });
    return { element: box, read: () => box.checked };
  }
  // Three states: left out (the default), true, false.
  const select = el(ctx, 'select', { 'aria-label': path });
  const d = c.schema.default;
  select.append(
    el(ctx, 'option', { value: '' }, d === undefined || d === null ? '(not set)' : `(default: ${d})`),
    el(ctx, 'option', { value: 'true' }, 'true'),
    el(ctx, 'option', { value: 'false' }, 'false'),
  );
  select.value = value === true ? 'true' : value === false ? 'false' : '';
  return { element: select, read: () => (select.value === '' ? undefined : select.value === 'true') };
}

function numberEditor(c, value, path, ctx) {
  const s = c.schema;
  const integer = c.kind === 'integer';
  const [fmin, fmax] = FORMAT_BOUNDS[s.format] || [];
  const min = s.minimum ?? fmin;
  const max = s.maximum ?? fmax;
  // u64/i64 past 2^53 do not fit an <input type=number>: text with a digits pattern.
  const wide = integer && !(s.format in FORMAT_BOUNDS) && !('maximum' in s);
  const input = el(ctx, 'input', {
    type: wide ? 'text' : 'number',
    inputMode: integer ? 'numeric' : 'decimal',
    step: wide ? undefined : integer ? '1' : 'any',
    min: wide ? undefined : min,
    max: wide ? undefined : max,
    pattern: wide ? '-?[0-9]+' : undefined,
    placeholder: placeholder(s),
    value: value === undefined || value === null ? '' : String(value),
    'aria-label': path,
  });
  return {
    element: input,
    read() {
      if (input.value.trim() === '') {
        // <input type=number> reads '' for text it cannot parse: that is an error, not a blank.
        if (input.validity && input.validity.badInput) throw new FormError(`${path}: not a number`);
        return undefined;
      }
      const v = integer ? readInteger(input.value, path) : readNumber(input.value, path);
      if ((min !== undefined && v < min) || (max !== undefined && v > max)) {
        throw new FormError(`${path}: ${v} is outside [${min ?? '−∞'}, ${max ?? '∞'}]`);
      }
      return v;
    },
  };
}

function placeholder(s) {
  if (s.default !== undefined && s.default !== null) return `default: ${stringifyJson(s.default)}`;
  return undefined;
}

function stringEditor(c, value, path, ctx) {
  const input = el(ctx, 'input', { type: 'text', placeholder: placeholder(c.schema), value: value ?? '', 'aria-label': path });
  return { element: input, read: () => (input.value === '' ? undefined : input.value) };
}

/** Fields of the properties of `s`, in a definition list; `fixed` = { key: value } shown as text. */
function propertiesEditor(s, value, path, ctx, fixed = {}) {
  const dl = el(ctx, 'dl', { class: 'schema-object' });
  const fields = [];
  const requiredKeys = new Set(s.required || []);
  for (const [key, prop] of Object.entries(s.properties)) {
    if (key in fixed) continue;
    const sub = editor(prop, value && typeof value === 'object' ? value[key] : undefined, `${path}.${key}`, ctx, requiredKeys.has(key));
    const label = el(ctx, 'dt', { title: resolve(prop, ctx.root).description || '' }, key + (requiredKeys.has(key) ? ' *' : ''));
    dl.append(label, el(ctx, 'dd', {}, sub.element));
    fields.push([key, sub]);
  }
  const read = () => {
    const out = { ...fixed };
    for (const [key, sub] of fields) {
      const v = sub.read();
      if (v !== undefined) out[key] = v;
    }
    return out;
  };
  return { element: dl, read };
}

function objectEditor(c, value, path, ctx, required) {
  const e = propertiesEditor(c.schema, value, path, ctx);
  return {
    element: e.element,
    read() {
      const v = e.read();
      return required || Object.keys(v).length ? v : undefined;
    },
  };
}

function optionalEditor(c, value, path, ctx) {
  const present = value !== undefined && value !== null;
  const box = el(ctx, 'input', { type: 'checkbox', checked: present, 'aria-label': `${path} set` });
  const holder = el(ctx, 'div', { class: 'schema-optional' });
  let inner = null;
  const build = () => {
    if (inner) return;
    inner = editor(c.inner, value ?? undefined, path, ctx, true);
    holder.append(inner.element);
  };
  if (present) build();
  holder.hidden = !present;
  box.addEventListener('change', () => {
    if (box.checked) build();
    holder.hidden = !box.checked;
  });
  const element = el(ctx, 'div', { class: 'schema-optional-field' }, el(ctx, 'label', { class: 'dim' }, box, ' set'), holder);
  return { element, read: () => (box.checked && inner ? inner.read() : undefined) };
}

function unionEditor(c, value, path, ctx, required) {
  const branches = (c.schema.oneOf || c.schema.anyOf).filter((b) => !isNull(b)).map((b) => resolve(b, ctx.root));
  const tag = unionTag(branches, ctx.root);
  const tagOf = (b) => resolve(b.properties[tag], ctx.root).const;
  const select = el(ctx, 'select', { 'aria-label': `${path}.${tag}` });
  if (!required || c.nullable) select.append(el(ctx, 'option', { value: '' }, '(not set)'));
  branches.forEach((b, i) => select.append(el(ctx, 'option', { value: String(i), title: b.description || '' }, String(tagOf(b)))));
  const holder = el(ctx, 'div', { class: 'schema-union' });
  let current = null;
  const show = (i, v) => {
    holder.replaceChildren();
    current = null;
    if (i === '') return;
    const b = branches[Number(i)];
    current = propertiesEditor(b, v, path, ctx, { [tag]: tagOf(b) });
    holder.append(current.element);
  };
  const at = value && typeof value === 'object' ? branches.findIndex((b) => tagOf(b) === value[tag]) : -1;
  select.value = at >= 0 ? String(at) : required && !c.nullable ? '0' : '';
  show(select.value, at >= 0 ? value : undefined);
  select.addEventListener('change', () => show(select.value, undefined));
  const element = el(ctx, 'div', { class: 'schema-union-field' }, el(ctx, 'label', { class: 'dim' }, `${tag} `, select), holder);
  return { element, read: () => (current ? current.read() : undefined) };
}

function tupleEditor(c, value, path, ctx, required) {
  const n = c.schema.minItems;
  const items = Array.from({ length: n }, (_, i) =>
    editor(c.schema.items, Array.isArray(value) ? value[i] : undefined, `${path}[${i}]`, ctx, true),
  );
  const d = c.schema.default;
  if (Array.isArray(d) && !Array.isArray(value)) items.forEach((e, i) => e.element.setAttribute('placeholder', String(d[i])));
  const element = el(ctx, 'div', { class: 'schema-tuple' }, ...items.map((e) => e.element));
  return {
    element,
    read() {
      const v = items.map((e) => e.read());
      if (v.every((x) => x === undefined) && !required) return undefined;
      const missing = v.findIndex((x) => x === undefined);
      if (missing >= 0) throw new FormError(`${path}[${missing}]: empty (all ${n} values are needed)`);
      return v;
    },
  };
}

/** Lists longer than this start folded. */
const LIST_OPEN = 4;

function listEditor(c, value, path, ctx, required) {
  const list = el(ctx, 'ol', { class: 'schema-list' });
  // Long lists (an event table's cells) start folded, under their count.
  const summary = el(ctx, 'summary', {});
  const entries = [];
  const changed = () => (summary.textContent = `${entries.length} ${entries.length === 1 ? 'entry' : 'entries'}`);
  const add = (v) => {
    const sub = editor(c.schema.items, v, `${path}[${entries.length}]`, ctx, true);
    const remove = el(ctx, 'button', { type: 'button', class: 'schema-remove', title: 'Remove this entry' }, '×');
    const li = el(ctx, 'li', {}, remove, sub.element);
    const entry = { li, sub };
    remove.addEventListener('click', () => {
      entries.splice(entries.indexOf(entry), 1);
      li.remove();
      renumber();
    });
    entries.push(entry);
    list.append(li);
    changed();
  };
  // After a removal the entries are made again, so their paths (in labels and in the errors
  // that name them) follow their new places; while one cannot be read they stay as they are.
  const renumber = () => {
    let values;
    try {
      values = entries.map((e) => e.sub.read());
    } catch (e) {
      if (!(e instanceof FormError)) throw e;
      return changed();
    }
    entries.splice(0).forEach((e) => e.li.remove());
    values.forEach(add);
    changed();
  };
  if (Array.isArray(value)) value.forEach(add);
  changed();
  const addButton = el(ctx, 'button', { type: 'button', class: 'schema-add' }, 'Add');
  addButton.addEventListener('click', () => add(undefined));
  const element = el(ctx, 'details', { class: 'schema-list-field', open: entries.length <= LIST_OPEN }, summary, list, addButton);
  return {
    element,
    read() {
      const v = entries.map((e) => e.sub.read());
      return v.length || required ? v : undefined;
    },
  };
}

/** The JSON fallback: a text area holding the field's JSON; empty leaves it out. */
function jsonEditor(c, value, path, ctx) {
  const text = value === undefined ? '' : stringifyJson(value);
  const area = el(ctx, 'textarea', { class: 'schema-json', rows: Math.min(6, 1 + Math.floor(text.length / 40)), placeholder: placeholder(c.schema) ?? 'JSON', 'aria-label': path, spellcheck: false });
  area.value = text;
  return {
    element: area,
    read() {
      if (area.value.trim() === '') return undefined;
      try {
        return parseJson(area.value);
      } catch (e) {
        throw new FormError(`${path}: not JSON (${e.message})`);
      }
    },
  };
}
