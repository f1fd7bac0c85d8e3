// Prints deploy/k8s/nginx-config.yaml, the ConfigMap of Kubernetes' nginx, made from
// docker/nginx.conf so that compose, the replicas test and Kubernetes run one configuration.
// Only what a cluster changes is rewritten: the replicas are the StatefulSet's pods, by their
// names under the headless Service, re-resolved while nginx runs; nginx runs unprivileged on a
// read-only root.
//   node deploy/k8s/nginx-config.mjs > deploy/k8s/nginx-config.yaml
import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { readNginxConf, rewrite } from '../../docker/nginx-conf.mjs';

const ROOT = join(dirname(fileURLToPath(import.meta.url)), '..', '..');

/** The headless Service and the StatefulSet of deploy/k8s/vtex.yaml, in the namespace of
 * namespace.yaml: pod i of the StatefulSet is `vtex-i.vtex-replicas.vtex.svc.cluster.local`. */
const SERVICE = 'vtex-replicas.vtex.svc.cluster.local';
const STATEFUL_SET = 'vtex';
const PORT = 8080;
/** The cluster's DNS Service, by the name every distribution gives it. */
const CLUSTER_DNS = 'kube-dns.kube-system.svc.cluster.local';

/** The StatefulSet's replica count, read from vtex.yaml. */
function replicaCount() {
  const found = [...readFileSync(join(ROOT, 'deploy', 'k8s', 'vtex.yaml'), 'utf8').matchAll(/^  replicas: (\d+)$/gm)];
  if (found.length !== 1) throw new Error(`deploy/k8s/vtex.yaml: expected one "  replicas: N", found ${found.length}`);
  return Number(found[0][1]);
}

/** host:port of every replica, by its pod's stable name. */
export function replicas() {
  return Array.from({ length: replicaCount() }, (_, i) => `${STATEFUL_SET}-${i}.${SERVICE}:${PORT}`);
}

/** docker/nginx.conf as Kubernetes runs it. */
function k8sNginxConf() {
  let conf = readNginxConf();
  // `auto` counts the node's cores, not the pod's share of them.
  conf = rewrite(conf, /worker_processes auto;/, 'worker_processes 2;', 1);
  conf = rewrite(conf, /\/var\/run\/nginx\.pid/, '/tmp/nginx.pid', 1);
  // An unprivileged nginx cannot bind port 80; the Service maps 80 to this port.
  conf = rewrite(conf, /listen 80;/, 'listen 8080;', 1);
  // The cluster's DNS Service in place of the container's resolver that compose's start script
  // names (docker/nginx-start.sh).
  conf = rewrite(
    conf,
    /\n    include \/etc\/nginx\/resolver\.conf;/,
    [`\n    resolver ${CLUSTER_DNS} valid=5s;`, '    resolver_timeout 2s;'].join('\n'),
    1,
  );
  // Compose's named replicas become the StatefulSet's pods, each by its own name: nginx places
  // a server on the hash ring by its name, so every pod needs one (the addresses of one name
  // would share one place, and requests would go round-robin), and a pod that comes back at
  // another address takes its old place.
  conf = rewrite(
    conf,
    /(\n        server vtex-\d+:8080 [^\n]*;)+/,
    (lines) => {
      const params = lines.split('\n')[1].trim().split(' ').slice(2).join(' ');
      return replicas().map((r) => `\n        server ${r} ${params}`).join('');
    },
    1,
  );
  return conf;
}

/** The ConfigMap holding `conf` as its nginx.conf. */
function configMap(conf) {
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
