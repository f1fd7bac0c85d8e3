// The schema subset the parameter form understands (client-web/src/viewer/schema-form.js): which
// field each kind of schema gets, and JSON that keeps u64 integers exact.
import test from 'node:test';
import assert from 'node:assert/strict';
import { FormError, classify, parseJson, readInteger, readNumber, resolve, stringifyJson, unionTag } from '../src/viewer/schema-form.js';

const root = {
  $defs: {
    Order: { oneOf: [{ const: 'top_down', type: 'string' }, { const: 'bottom_up', type: 'string' }] },
    Lower: { enum: ['square3', 'square5'], type: 'string' },
    Kernel: { type: 'object', properties: { size: { type: 'integer', format: 'uint32', minimum: 0 } }, required: ['size'] },
    Map: {
      oneOf: [
        { type: 'object', properties: { kind: { const: 'logistic', type: 'string' }, r: { type: 'number' } }, required: ['kind', 'r'] },
        { type: 'object', properties: { kind: { const: 'tent', type: 'string' }, mu: { type: 'number' } }, required: ['kind', 'mu'] },
      ],
    },
    Palette: { anyOf: [{ type: 'string' }, { type: 'array', items: { type: 'number' } }] },
  },
};
const kind = (s) => classify(s, root).kind;

test('each schema shape gets its field', () => {
  assert.equal(kind({ type: 'integer', minimum: 0 }), 'integer');
  assert.equal(kind({ type: ['number', 'null'] }), 'number');
  assert.equal(classify({ type: ['number', 'null'] }, root).nullable, true);
  assert.equal(kind({ type: 'boolean' }), 'boolean');
  assert.equal(kind({ type: 'string' }), 'string');
  assert.equal(kind({ $ref: '#/$defs/Order', default: 'top_down' }), 'enum');
  assert.equal(kind({ $ref: '#/$defs/Lower' }), 'enum');
  assert.equal(kind({ $ref: '#/$defs/Kernel' }), 'object');
  assert.equal(kind({ anyOf: [{ $ref: '#/$defs/Kernel' }, { type: 'null' }] }), 'optional');
  assert.equal(kind({ type: ['array', 'null'], items: { type: 'number' }, minItems: 2, maxItems: 2 }), 'optional');
  assert.equal(kind({ $ref: '#/$defs/Map' }), 'union');
  assert.equal(unionTag(root.$defs.Map.oneOf, root), 'kind');
  assert.equal(kind({ type: 'array', items: { type: 'number' }, minItems: 4, maxItems: 4 }), 'tuple');
  assert.equal(kind({ type: 'array', items: { $ref: '#/$defs/Kernel' } }), 'list');
  assert.equal(kind({ type: 'array', items: { $ref: '#/$defs/Map' } }), 'list');
  // What a form cannot express well is edited as JSON.
  assert.equal(kind({ $ref: '#/$defs/Palette' }), 'json');
  assert.equal(kind({ type: 'array', items: { type: 'number' } }), 'json', 'a number list of any length');
  assert.equal(kind({ type: 'object', additionalProperties: { $ref: '#/$defs/Kernel' } }), 'json', 'a map by name');
  assert.equal(kind({ type: 'array', prefixItems: [{ type: 'number' }, { type: 'string' }] }), 'json');
  assert.equal(kind({}), 'json');
});

test('a reference keeps the keywords beside it and an unknown one is an error', () => {
  assert.deepEqual(resolve({ $ref: '#/$defs/Order', default: 'top_down' }, root).default, 'top_down');
  assert.throws(() => resolve({ $ref: '#/$defs/Nope' }, root), /#\/\$defs\/Nope not found/);
});

test('integers past 2^53 survive parsing, editing and writing back', () => {
  const text = '{"seed":18446744073709551615,"small":3,"x":0.5,"list":[9007199254740993]}';
  const v = parseJson(text);
  assert.equal(v.seed, 18446744073709551615n);
  assert.equal(v.small, 3);
  assert.equal(stringifyJson(v), text);
  assert.equal(readInteger(' 18446744073709551615 ', 'params.seed'), 18446744073709551615n);
  assert.equal(readInteger('42', 'params.seed'), 42);
  assert.throws(() => readInteger('4.5', 'params.seed'), (e) => e instanceof FormError && /params\.seed: "4\.5" is not an integer/.test(e.message));
  assert.equal(readNumber('1e-3', 'params.r'), 0.001);
  assert.throws(() => readNumber('x', 'params.r'), /params\.r: "x" is not a number/);
});

test('only integer tokens are read as BigInt: not digits in strings, fractions or exponents', () => {
  const v = parseJson('{"s":"12345678901234567890","f":0.12345678901234567,"e":1e12345678901234567,"n":-12345678901234567890}');
  assert.equal(v.s, '12345678901234567890');
  assert.equal(v.f, 0.12345678901234567);
  assert.equal(v.e, Infinity);
  assert.equal(v.n, -12345678901234567890n);
  assert.equal(parseJson('[1234567890123456]')[0], 1234567890123456, 'a safe 16-digit integer stays a Number');
  assert.equal(parseJson('"a\\"12345678901234567890"'), 'a"12345678901234567890');
});
