// Which texture a link's `texture=` names: its full id, its name, or a unique prefix of its id
// (at least MIN_PREFIX characters, so a short typo never picks a texture by chance).
export const MIN_PREFIX = 4;

/** The texture of `textures` that `key` names, or null when it names none or several. */
export function findTexture(textures, key) {
  if (!key) return null;
  const exact = textures.find((t) => t.id === key) || textures.find((t) => t.name === key);
  if (exact) return exact;
  if (key.length < MIN_PREFIX) return null;
  const prefix = key.toLowerCase();
  const matches = textures.filter((t) => t.id.startsWith(prefix));
  return matches.length === 1 ? matches[0] : null;
}
