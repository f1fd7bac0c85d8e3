"""Runs the vtex container of deploy/k8s/vtex.yaml as a process: its args and environment (the
values it sets, the core count read from its CPU limit, the write token file), its data
directory a temporary one. Checks that vtex starts with them, that every probe's path answers
200, that the budgets the server reports are the ones the manifest sets, and that the memory
limit holds them with the room the soak measured (BENCHMARKS.md, "Bounds under load": RSS
reached 1.13 x the budgets' sum at worst, 1.28 x with the system allocator).

    python3 deploy/k8s/check_vtex_pod.py VTEX_BIN
"""

import math
import re
import sys
import tempfile
import urllib.request
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from vtex_process import serving  # noqa: E402

MIB = 1024 * 1024
# The soak's worst RSS over its budgets' sum, with room (1.13 measured).
MEMORY_OVER_BUDGETS = 1.25
# Budget gauges vtex reports, by the variable that sets each (MiB).
BUDGETS = {
    "VTEX_CACHE_MB": "vtex_tile_cache_budget_bytes",
    "VTEX_TEXTURES_MB": "vtex_textures_budget_bytes",
    "VTEX_SYNTH_CACHE_MB": "vtex_model_cache_budget_bytes",
    "VTEX_INFLIGHT_MB": "vtex_inflight_budget_bytes",
}


def quantity(q):
    """A Kubernetes quantity of bytes or cores, as a number."""
    units = {"Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "m": 1e-3, "": 1}
    number, unit = re.fullmatch(r"([0-9.]+)([A-Za-z]*)", str(q)).groups()
    return float(number) * units[unit]


def get(url):
    with urllib.request.urlopen(url, timeout=30) as r:
        return r.status, r.read().decode()


def main():
    vtex_bin = sys.argv[1]
    docs = yaml.safe_load_all(Path("deploy/k8s/vtex.yaml").read_text())
    pod = next(d for d in docs if d["kind"] == "StatefulSet")["spec"]["template"]["spec"]
    container = pod["containers"][0]
    limits = container["resources"]["limits"]
    mounts = {m["name"]: m["mountPath"] for m in container["volumeMounts"]}
    with tempfile.TemporaryDirectory() as tmp:
        env = {"PATH": "/usr/bin:/bin", "VTEX_DATA_DIR": f"{tmp}/data", "VTEX_LOG": "warn"}
        from_secrets = []
        for var in container["env"]:
            source = var.get("valueFrom", {})
            if "value" in var:
                env[var["name"]] = var["value"]
            elif "resourceFieldRef" in source:
                ref = source["resourceFieldRef"]
                kind = ref["resource"].split(".", 1)[1]
                env[var["name"]] = str(math.ceil(quantity(limits[kind]) / quantity(ref.get("divisor", "1"))))
            elif "secretKeyRef" in source:
                from_secrets.append(var["name"])
        # The token file where the manifest mounts it, under the temporary directory.
        token_file = Path(env["VTEX_WRITE_TOKEN_FILE"])
        mounted = Path(tmp) / token_file.relative_to("/")
        assert str(token_file.parent) == mounts["write-token"], "VTEX_WRITE_TOKEN_FILE is not in the token's mount"
        mounted.parent.mkdir(parents=True)
        mounted.write_text("check-token")
        env["VTEX_WRITE_TOKEN_FILE"] = str(mounted)
        port = container["ports"][0]["containerPort"]
        assert env["VTEX_BIND"] == f"0.0.0.0:{port}", f"VTEX_BIND is not the container port {port}"
        env["VTEX_BIND"] = "127.0.0.1:0"
        with serving(vtex_bin, container["args"], env) as base:
            for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
                status, _ = get(base + container[probe]["httpGet"]["path"])
                assert status == 200, f"{probe}: {status}"
            _, metrics = get(f"{base}/metrics")
    reported = dict(re.findall(r"^(vtex_\w+_budget_bytes) (\d+)$", metrics, re.M))
    total = 0
    for var, gauge in BUDGETS.items():
        want = float(env[var]) * MIB
        assert float(reported[gauge]) == want, f"{gauge} is {reported[gauge]}, the manifest's {var} says {want:.0f}"
        total += want
    memory = quantity(limits["memory"])
    assert quantity(container["resources"]["requests"]["memory"]) == memory, "memory request differs from the limit"
    assert memory >= MEMORY_OVER_BUDGETS * total, (
        f"memory limit {memory / MIB:.0f} MiB is under {MEMORY_OVER_BUDGETS} x the budgets' {total / MIB:.0f} MiB"
    )
    print(
        f"deploy/k8s/vtex.yaml: vtex starts with its environment ({env['VTEX_MAX_SYNTHESES']} synthesis slots from "
        f"the CPU limit; from Secrets: {', '.join(from_secrets)}), its probes answer, budgets {total / MIB:.0f} MiB "
        f"within the {memory / MIB:.0f} MiB limit ({memory / total:.2f} x)"
    )


if __name__ == "__main__":
    main()
