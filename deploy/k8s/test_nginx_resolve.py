"""The cluster's nginx.conf (deploy/k8s/nginx-config.yaml) running, its replicas found as on
Kubernetes: each pod of the StatefulSet by its own name, which the cluster's DNS answers while
the pod is ready. Here the pods are `vtex serve` processes on 127.0.0.2-4 (one port), the DNS
server is dnslib's on loopback, and nginx is one with `resolve` (1.27.3 or later). nginx must
follow the answers while it runs, and keep hashing: once settled, one URI always reaches the
same pod, a pod that goes hands only its own URIs to the others, and takes them back when it
returns.

    python3 deploy/k8s/test_nginx_resolve.py VTEX_BIN NGINX_BIN
"""

import json
import re
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections import Counter
from pathlib import Path

import yaml
from dnslib import QTYPE, RCODE, RR, A
from dnslib.server import BaseResolver, DNSLogger, DNSServer

PODS = ["127.0.0.2", "127.0.0.3", "127.0.0.4"]
# What nginx is told: look the names up again every second (the cluster's config says 5 s);
# a change of the answers is given two seconds more than that to be seen.
VALID = 1


class ClusterDns(BaseResolver):
    """Answers each ready pod's name with its address, and the others with NXDOMAIN, as the
    cluster's DNS answers a StatefulSet's pods under their headless Service."""

    def __init__(self):
        self.ready = {}

    def resolve(self, request, handler):
        reply = request.reply()
        name = str(request.q.qname).rstrip(".")
        if name not in self.ready:
            reply.header.rcode = RCODE.NXDOMAIN
        elif request.q.qtype == QTYPE.A:
            reply.add_answer(RR(name + ".", QTYPE.A, rdata=A(self.ready[name]), ttl=VALID))
        return reply


def free_port(host):
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def free_port_on_all(hosts):
    """A port free on every host (found on the first, checked on the others)."""
    for _ in range(50):
        port = free_port(hosts[0])
        try:
            for host in hosts[1:]:
                with socket.socket() as s:
                    s.bind((host, port))
            return port
        except OSError:
            continue
    sys.exit("no port free on every pod address")


def start_vtex(vtex, addr, data, demos):
    proc = subprocess.Popen(
        [vtex, "serve", "--bind", addr, "--data-dir", data, *([] if demos else ["--no-demos"])],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env={"PATH": "/usr/bin:/bin", "VTEX_LOG": "warn"},
        text=True,
    )
    if not proc.stdout.readline().startswith("vtex listening on"):
        sys.exit(f"vtex on {addr} did not start")
    return proc


def rewrite(text, old, new, count=1):
    if text.count(old) != count:
        sys.exit(f"nginx-config.yaml: expected {count} x {old!r}, found {text.count(old)}")
    return text.replace(old, new)


def main():
    vtex, nginx = sys.argv[1:3]
    conf = yaml.safe_load(Path("deploy/k8s/nginx-config.yaml").read_text())["data"]["nginx.conf"]
    servers = re.findall(r"server (\S+):(\d+) resolve", conf)
    if len(servers) != len(PODS):
        sys.exit(f"nginx-config.yaml names {len(servers)} replicas; this test runs {len(PODS)}")
    names = [name for name, _ in servers]
    dns = ClusterDns()
    dns_port = free_port("127.0.0.1")
    server = DNSServer(dns, port=dns_port, address="127.0.0.1", logger=DNSLogger(logf=lambda _: None))
    server.start_thread()
    procs = []
    with tempfile.TemporaryDirectory() as tmp:
        try:
            vtex_port = free_port_on_all(PODS)
            for i, pod in enumerate(PODS):
                procs.append(start_vtex(vtex, f"{pod}:{vtex_port}", f"{tmp}/data", demos=i == 0))
            listen = free_port("127.0.0.1")
            conf = re.sub(r"resolver \S+ valid=\d+s;", f"resolver 127.0.0.1:{dns_port} valid={VALID}s;", conf)
            for name, port in servers:
                conf = rewrite(conf, f"server {name}:{port} resolve", f"server {name}:{vtex_port} resolve")
            conf = rewrite(conf, "listen 8080;", f"listen 127.0.0.1:{listen};")
            conf = rewrite(conf, "/var/cache/nginx", f"{tmp}/cache", 6)
            conf = rewrite(conf, "/tmp/nginx.pid", f"{tmp}/nginx.pid")
            conf = rewrite(conf, "access_log /dev/stdout", f"access_log {tmp}/access.log")
            Path(f"{tmp}/nginx.conf").write_text(conf)
            # nginx started as root runs its workers unprivileged: they write the cache here.
            Path(tmp).chmod(0o755)
            Path(f"{tmp}/cache").mkdir()
            Path(f"{tmp}/cache").chmod(0o777)
            dns.ready = dict(zip(names, PODS))
            # Its log (a name not resolved is logged as an error) is shown only if the test fails.
            nginx_log = open(f"{tmp}/nginx.err", "w")
            procs.append(
                subprocess.Popen(
                    [nginx, "-p", tmp, "-c", f"{tmp}/nginx.conf", "-e", "stderr", "-g", "daemon off;"], stderr=nginx_log
                )
            )
            base = f"http://127.0.0.1:{listen}"
            log = Path(f"{tmp}/access.log")
            # nginx resolves the names once it runs: until the first answers, no replica (502).
            for _ in range(100):
                try:
                    listing = urllib.request.urlopen(f"{base}/api/v1/textures", timeout=30).read()
                    break
                except (urllib.error.HTTPError, ConnectionError, urllib.error.URLError):
                    if procs[-1].poll() is not None:
                        sys.exit("nginx did not start")
                    time.sleep(0.05)
            else:
                sys.exit("nginx found no replica by their names within 5 s")
            textures = json.loads(listing)["textures"]
            mosaic = max((t for t in textures if t["model"] == "chaos-mosaic"), key=lambda t: t["width"])
            row = [0]

            def answered_by(paths):
                """The pod nginx chose first for each path (a retry after an error may be another)."""
                seen = len(log.read_text().splitlines()) if log.exists() else 0
                for path in paths:
                    with urllib.request.urlopen(base + path, timeout=30) as r:
                        assert r.status == 200 and r.read(), path
                # nginx logs a request once it is done, which may be just after its client read it.
                for _ in range(100):
                    lines = log.read_text().splitlines()[seen:]
                    if len(lines) >= len(paths):
                        break
                    time.sleep(0.02)
                assert len(lines) == len(paths), f"{len(lines)} log lines for {len(paths)} requests"
                return [re.search(r"upstream=(\S+)", line).group(1).split(", ")[0].split(":")[0] for line in lines]

            # Texture info: never cached by nginx, so every request reaches a pod.
            infos = [f"/api/v1/textures/{t['id']}" for t in textures]

            def step(what, ready):
                dns.ready = {names[i]: PODS[i] for i in ready}
                time.sleep(VALID + 2)
                tiles = [f"/api/v1/textures/{mosaic['id']}/tiles/0/{x}/{row[0]}.jpg" for x in range(60)]
                row[0] += 1
                spread = Counter(answered_by(tiles))
                assert set(spread) == {PODS[i] for i in ready}, f"{what}: tiles came from {dict(spread)}"
                # Each worker rebuilds its hash ring when it next sees the changed servers: for a
                # moment the two workers may place a URI apart. Settled means two passes agree.
                placed = answered_by(infos)
                for _ in range(5):
                    again = answered_by(infos)
                    if again == placed:
                        break
                    placed = again
                    time.sleep(0.5)
                else:
                    sys.exit(f"{what}: the URIs' pods never settled: {list(zip(infos, placed))}")
                print(f"{what}: 60 new tiles, all 200, from {', '.join(f'{p} ({n})' for p, n in sorted(spread.items()))}")
                return placed

            everyone = step("three pods ready", [0, 1, 2])
            without = step("the first pod not ready", [1, 2])
            moved = [(a, b) for a, b in zip(everyone, without) if a != b]
            assert moved and all(a == PODS[0] for a, _ in moved), f"URIs moved between the pods that stayed: {moved}"
            print(f"  {len(moved)} of {len(infos)} URIs moved, all of them the first pod's")
            back = step("the first pod ready again", [0, 1, 2])
            assert back == everyone, "the first pod did not take its URIs back"
            print("  every URI back where it was")
        except BaseException:
            if Path(f"{tmp}/nginx.err").exists():
                print(Path(f"{tmp}/nginx.err").read_text()[-4000:], file=sys.stderr)
            raise
        finally:
            for p in procs:
                p.terminate()
            for p in procs:
                p.wait(timeout=15)
            server.stop()


if __name__ == "__main__":
    main()
