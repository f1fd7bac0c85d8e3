// Prints deploy/k8s/nginx-config.yaml, the ConfigMap of Kubernetes' nginx, made from
// docker/nginx.conf so that compose, the replicas test and Kubernetes run one configuration.
// Only what a cluster changes is rewritten: the replicas are the pods behind the headless
// Service, re-resolved while nginx runs; nginx runs unprivileged on a read-only root.
//   node deploy/k8s/nginx-config.mjs > deploy/k8s/nginx-config.yaml
import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const ROOT = join(dirname(fileURLToPath(import.meta.url)), '..', '..');

/** The headless Service of deploy/k8s/vtex.yaml, in the namespace of namespace.yaml. */
export const REPLICAS = 'vtex-replicas.vtex.svc.cluster.local:8080';
/** The cluster's DNS Service, by the name every distribution gives it. */
export const CLUSTER_DNS = 'kube-dns.kube-system.svc.cluster.local';

/** Replaces `pattern` in `text`, requiring exactly `count` matches: a docker/nginx.conf that
 * drifted from what is rewritten fails loudly instead of shipping something else. */
function rewrite(text, pattern, replace, count) {
  const found = text.match(new RegExp(pattern.source, 'g')) || [];
  if (found.length !== count) throw new Error(`docker/nginx.conf: expected ${count} × ${pattern}, found ${found.length}`);
  return text.replace(new RegExp(pattern.source, 'g'), replace);
}

/** docker/nginx.conf as Kubernetes runs it. */
export function k8sNginxConf() {
  let conf = readFileSync(join(ROOT, 'docker', 'nginx.conf'), 'utf8');
  // `auto` counts the node's cores, not the pod's share of them.
  conf = rewrite(conf, /worker_processes auto;/, 'worker_processes 2;', 1);
  conf = rewrite(conf, /\/var\/run\/nginx\.pid/, '/tmp/nginx.pid', 1);
  // An unprivileged nginx cannot bind port 80; the Service maps 80 to this port.
  conf = rewrite(conf, /listen 80;/, 'listen 8080;', 1);
  conf = rewrite(
    conf,
    /\n    upstream vtex \{/,
    [
      '',
      '    # The replicas come and go: their names are looked up again every 5 s while nginx runs.',
      `    resolver ${CLUSTER_DNS} valid=5s;`,
      '    resolver_timeout 2s;',
      '',
      '    upstream vtex {',
      '        # Shared by the workers, so that a re-resolved set of replicas is one for all of them.',
      '        zone vtex_replicas 1m;',
    ].join('\n'),
    1,
  );
  // Compose's three named replicas become every ready pod behind the headless Service.
  conf = rewrite(
    conf,
    /(\n        server vtex-\d+:8080 [^\n]*;)+/,
    (lines) => `\n        server ${REPLICAS} resolve ${lines.split('\n')[1].trim().split(' ').slice(2).join(' ')}`,
    1,
  );
  return conf;
}

/** The ConfigMap holding `conf` as its nginx.conf. */
export function configMap(conf) {
  const body = conf
    .trimEnd()
    .split('\n')
    .map((line) => (line ? `    ${line}` : ''))
    .join('\n');
  return `# Generated from docker/nginx.conf by deploy/k8s/nginx-config.mjs: edit that file, then run
#   node deploy/k8s/nginx-config.mjs > deploy/k8s/nginx-config.yaml
# (deploy/check.sh fails while this file differs from what the script prints).
apiVersion: v1
kind: ConfigMap
metadata:
  name: vtex-nginx
  namespace: vtex
  labels:
    app.kubernetes.io/name: vtex
    app.kubernetes.io/component: proxy
    app.kubernetes.io/part-of: vtex
data:
  nginx.conf: |
${body}
`;
}

if (process.argv[1] === fileURLToPath(import.meta.url)) process.stdout.write(configMap(k8sNginxConf()));
