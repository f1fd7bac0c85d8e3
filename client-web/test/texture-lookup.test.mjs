// Which texture a link names (client-web/src/shared/texture-lookup.js).
import test from 'node:test';
import assert from 'node:assert/strict';
import { MIN_PREFIX, findTexture } from '../src/shared/texture-lookup.js';

const textures = [
  { id: 'ab12' + '0'.repeat(60), name: 'Pebbles' },
  { id: 'ab34' + '1'.repeat(60), name: 'Leaves' },
  { id: 'cd56' + '2'.repeat(60), name: 'ab12' },
];

test('a link names a texture by id, by name, or by a unique id prefix', () => {
  assert.equal(findTexture(textures, textures[1].id), textures[1]);
  assert.equal(findTexture(textures, 'Leaves'), textures[1]);
  assert.equal(findTexture(textures, 'ab12'), textures[2], 'a name beats a prefix');
  assert.equal(findTexture(textures, 'ab120'), textures[0]);
  assert.equal(findTexture(textures, 'CD56'), textures[2], 'ids are hex: case does not matter');
  assert.equal(findTexture(textures, 'ab3'.padEnd(MIN_PREFIX, '4')), textures[1], 'exactly the minimum');
});

test('an ambiguous, too short or unknown key names none', () => {
  assert.equal(findTexture(textures, 'ab'), null, 'shorter than the minimum');
  assert.equal(findTexture(textures, 'ab1'), null);
  assert.equal(findTexture(textures, 'ab3'), null, `under ${MIN_PREFIX} characters`);
  assert.equal(findTexture([...textures, { id: 'ab12f' + '3'.repeat(59), name: 'x' }], 'ab120'), textures[0]);
  assert.equal(findTexture([...textures, { id: 'ab120' + '3'.repeat(59), name: 'x' }], 'ab120'), null, 'two match');
  assert.equal(findTexture(textures, 'ffff'), null);
  assert.equal(findTexture(textures, ''), null);
});
