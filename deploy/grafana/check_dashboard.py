"""Checks deploy/grafana/vtex.json against what vtex really exports: every PromQL expression of
the dashboard parses (Prometheus's own parser: `promtool check rules` on them as recording
rules), and every metric it names is in the /metrics of a live `vtex serve` this script starts
and drives through the paths that make each series appear.

    python3 deploy/grafana/check_dashboard.py DASHBOARD VTEX_BIN PROMTOOL
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from vtex_process import serving  # noqa: E402

# Grafana's variables, replaced by values of their kind so that the expressions are PromQL.
VARIABLES = {"$__rate_interval": "5m", "$instance": ".*"}
# Names of series the server exports (the process_* family is the Prometheus client's).
METRIC = re.compile(r"\b(?:vtex|process)_[a-z0-9_]+\b")


def expressions(dashboard):
    """(where, PromQL) of every panel target and of the replica variable's query."""
    found = []
    for panel in dashboard["panels"]:
        for target in panel.get("targets", []):
            found.append((f'panel "{panel["title"]}" {target["refId"]}', target["expr"]))
    for var in dashboard["templating"]["list"]:
        if var["type"] == "query":
            # label_values(METRIC, label) is Grafana's: the metric is what must exist.
            m = re.fullmatch(r"label_values\((\w+), *\w+\)", var["query"]["query"])
            if not m:
                sys.exit(f'variable {var["name"]}: not a label_values(metric, label) query')
            found.append((f'variable {var["name"]}', m.group(1)))
    return found


def as_promql(where, expr):
    for name, value in VARIABLES.items():
        expr = expr.replace(name, value)
    if "$" in expr:
        sys.exit(f"{where}: a variable this check does not know: {expr}")
    return expr


def check_parses(exprs, promtool):
    rules = {
        "groups": [
            {
                "name": "vtex-dashboard",
                "rules": [{"record": f"vtex_dashboard:expr_{i}", "expr": e} for i, (_, e) in enumerate(exprs)],
            }
        ]
    }
    with tempfile.NamedTemporaryFile("w", suffix=".yaml") as f:
        json.dump(rules, f)  # JSON is YAML
        f.flush()
        done = subprocess.run([promtool, "check", "rules", f.name], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"promtool check rules refused the dashboard's expressions:\n{done.stdout}{done.stderr}")


def get(url, headers=None):
    with urllib.request.urlopen(urllib.request.Request(url, headers=headers or {}), timeout=60) as r:
        return r.read()


def live_metrics(vtex):
    """/metrics of a fresh `vtex serve` (the demos) after the requests that fill every family:
    tiles missed then hit in each format, a tile batch, an order-independent tile (the models'
    work counters), and a connection refused at the per-client limit."""
    with tempfile.TemporaryDirectory() as data:
        with serving(vtex, ["serve", "--bind", "127.0.0.1:0", "--data-dir", data, "--max-connections-per-client", "2"]) as base:
            textures = json.loads(get(f"{base}/api/v1/textures"))["textures"]
            for model in ("chaos-mosaic", "order-independent"):
                t = next(t for t in textures if t["model"] == model)
                for fmt in ("png", "webp", "jpg"):
                    for _ in range(2):
                        get(f"{base}/api/v1/textures/{t['id']}/tiles/{t['levels'] - 1}/0/0.{fmt}")
            get(f"{base}/api/v1/textures/{textures[0]['id']}/tiles?format=png&tiles=0/0/0,0/1/0")
            host, port = base.removeprefix("http://").rsplit(":", 1)
            held = [socket.create_connection((host, int(port))) for _ in range(2)]
            refused = socket.create_connection((host, int(port)))
            refused.settimeout(10)
            if b" 429 " not in refused.recv(200):
                sys.exit("the third connection of one client was not refused (429)")
            for s in [*held, refused]:
                s.close()
            # The server sees the held connections close a moment later; until then, 429.
            for _ in range(50):
                try:
                    return get(f"{base}/metrics").decode()
                except urllib.error.HTTPError as e:
                    if e.code != 429:
                        raise
                    time.sleep(0.1)
            sys.exit("/metrics stayed refused (429) after the held connections closed")

def main():
    dashboard_path, vtex, promtool = sys.argv[1:4]
    dashboard = json.loads(Path(dashboard_path).read_text())
    exprs = [(where, as_promql(where, e)) for where, e in expressions(dashboard)]
    check_parses(exprs, promtool)
    exported = {line.split("{")[0].split(" ")[0] for line in live_metrics(vtex).splitlines() if line and line[0] != "#"}
    missing = []
    for where, expr in exprs:
        names = METRIC.findall(expr)
        if not names:
            missing.append(f"{where}: names no vtex or process metric: {expr}")
        missing += [f"{where}: {n} is not in vtex's /metrics" for n in names if n not in exported]
    if missing:
        sys.exit("\n".join(missing))
    print(f"{dashboard_path}: {len(exprs)} expressions parse, and the {len({n for _, e in exprs for n in METRIC.findall(e)})} metrics they name are exported")


if __name__ == "__main__":
    main()
