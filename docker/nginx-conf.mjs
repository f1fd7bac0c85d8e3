// docker/nginx.conf, and the one way others rewrite it to run it elsewhere (tests/replicas on
// loopback, deploy/k8s on a cluster): each rewrite must match exactly as often as it expects,
// so a configuration that drifted from what is rewritten fails loudly instead of running
// something else.
import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

export const NGINX_CONF = join(dirname(fileURLToPath(import.meta.url)), 'nginx.conf');

export function readNginxConf() {
  return readFileSync(NGINX_CONF, 'utf8');
}

/** Replaces `pattern` (a function or a string as `replace`) in `text`, requiring exactly
 * `count` matches. */
export function rewrite(text, pattern, replace, count) {
  const found = text.match(new RegExp(pattern.source, 'g')) || [];
  if (found.length !== count) throw new Error(`docker/nginx.conf: expected ${count} × ${pattern}, found ${found.length}`);
  return text.replace(new RegExp(pattern.source, 'g'), replace);
}
