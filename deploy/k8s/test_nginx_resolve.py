"""The cluster's nginx.conf (deploy/k8s/nginx-config.yaml) running, with the replicas found as
on Kubernetes: by one name that a DNS server answers with every ready pod's address. Here the
pods are `vtex serve` processes on 127.0.0.2-4 (one port), the DNS server is dnslib's on
loopback, standing in for the cluster's, and nginx is one with `resolve` (1.27.3 or later).
As the answer changes (a pod added, a pod gone), nginx must follow it while it runs: tiles
reach exactly the pods the name answers, and none is lost.

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
from pathlib import Path

import yaml
from dnslib import QTYPE, RR, A
from dnslib.server import BaseResolver, DNSLogger, DNSServer

PODS = ["127.0.0.2", "127.0.0.3", "127.0.0.4"]
# What nginx is told: look the name up again every second (the cluster's config says 5 s);
# a change of the answer is given two seconds more than that to be seen.
VALID = 1


class Pods(BaseResolver):
    """Answers the replicas' name with the addresses in `ready`, as the cluster's DNS answers
    a headless Service with its ready pods."""

    def __init__(self, name):
        self.name = name.rstrip(".") + "."
        self.ready = []

    def resolve(self, request, handler):
        reply = request.reply()
        if str(request.q.qname) == self.name and request.q.qtype == QTYPE.A:
            for addr in self.ready:
                reply.add_answer(RR(self.name, QTYPE.A, rdata=A(addr), ttl=VALID))
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
    name, port = re.search(r"server (\S+):(\d+) resolve", conf).groups()
    pods = Pods(name)
    dns_port = free_port("127.0.0.1")
    dns = DNSServer(pods, port=dns_port, address="127.0.0.1", logger=DNSLogger(logf=lambda _: None))
    dns.start_thread()
    procs = []
    with tempfile.TemporaryDirectory() as tmp:
        try:
            vtex_port = free_port_on_all(PODS)
            data = f"{tmp}/data"
            for i, pod in enumerate(PODS):
                procs.append(start_vtex(vtex, f"{pod}:{vtex_port}", data, demos=i == 0))
            listen = free_port("127.0.0.1")
            conf = re.sub(r"resolver \S+ valid=\d+s;", f"resolver 127.0.0.1:{dns_port} valid={VALID}s;", conf)
            conf = rewrite(conf, f"server {name}:{port} resolve", f"server {name}:{vtex_port} resolve")
            conf = rewrite(conf, "listen 8080;", f"listen 127.0.0.1:{listen};")
            conf = rewrite(conf, "/var/cache/nginx", f"{tmp}/cache", 6)
            conf = rewrite(conf, "/tmp/nginx.pid", f"{tmp}/nginx.pid")
            conf = rewrite(conf, "access_log /dev/stdout", f"access_log {tmp}/access.log")
            Path(f"{tmp}/nginx.conf").write_text(conf)
            # nginx started as root runs its workers unprivileged: they write the cache here.
            Path(tmp).chmod(0o755)
            Path(f"{tmp}/cache").mkdir(mode=0o777)
            Path(f"{tmp}/cache").chmod(0o777)
            pods.ready = PODS[:2]
            procs.append(
                subprocess.Popen([nginx, "-p", tmp, "-c", f"{tmp}/nginx.conf", "-e", "stderr", "-g", "daemon off;"])
            )
            base = f"http://127.0.0.1:{listen}"
            for _ in range(200):
                try:
                    urllib.request.urlopen(f"{base}/nginx-health", timeout=2)
                    break
                except OSError:
                    if procs[-1].poll() is not None:
                        sys.exit("nginx did not start")
                    time.sleep(0.05)
            # nginx resolves the name once it runs: until the first answer, no replica (502).
            for _ in range(100):
                try:
                    listing = urllib.request.urlopen(f"{base}/api/v1/textures", timeout=30).read()
                    break
                except urllib.error.HTTPError as e:
                    if e.code != 502:
                        raise
                    time.sleep(0.05)
            else:
                sys.exit("nginx found no replica by the name within 5 s")
            textures = json.loads(listing)["textures"]
            texture = max((t for t in textures if t["model"] == "chaos-mosaic"), key=lambda t: t["width"])
            row = [0]

            def tiles_reach(expected, step):
                """60 distinct tiles through nginx, then the pods their answers came from."""
                log = Path(f"{tmp}/access.log")
                seen = len(log.read_text().splitlines()) if log.exists() else 0
                for x in range(60):
                    url = f"{base}/api/v1/textures/{texture['id']}/tiles/0/{x}/{row[0]}.jpg"
                    with urllib.request.urlopen(url, timeout=30) as r:
                        assert r.status == 200 and r.read(), f"{step}: {url}"
                row[0] += 1
                used = set()
                for line in log.read_text().splitlines()[seen:]:
                    used |= {a.split(":")[0] for a in re.findall(r"upstream=(\S+)", line)[0].split(", ")}
                assert used == set(expected), f"{step}: tiles reached {sorted(used)}, the name answers {expected}"
                print(f"{step}: 60 tiles, all 200, from {', '.join(sorted(used))}")

            tiles_reach(PODS[:2], "two pods ready")
            pods.ready = PODS
            time.sleep(VALID + 2)
            tiles_reach(PODS, "a third pod ready")
            pods.ready = PODS[1:]
            time.sleep(VALID + 2)
            tiles_reach(PODS[1:], "the first pod gone from the answer")
        finally:
            for p in procs:
                p.terminate()
            for p in procs:
                p.wait(timeout=15)
            dns.stop()


if __name__ == "__main__":
    main()
