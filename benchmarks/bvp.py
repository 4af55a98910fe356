"""Benchmark: two-point problems, the library against CasADi's rootfinder and Ipopt.

Problems (all start from the library's default geodesic guess, zero multipliers):

- ``rigid_body``: the second-order rest-to-rest attitude maneuver of
  ``examples/rigid_body_attitude.py`` (seed 001 §3.3.4, eq. (27)), h = T/(N − 1);
- ``so3``: the first-order SO(3) Cayley problem L = h·½ξᵀIξ, I = diag(1, 2, 3), ξ = cay⁻¹(g)/h
  (seed 000 §6.1), from the identity to exp((0.6, −0.4, 0.9)^), h = 1/N;
- ``se2``: the unicycle on SE(2) (``_bvp_problems.se2_system``, A = M = 1, v₂ = 0) to the pose
  (0.8, 0.6, 60°), h = 1/N.

For N = 250, 1000, 4000, 16000 each solver runs in its own process (so times, memory and
failures stay apart):

- the library cold: system construction, window-kernel derivation and the first solve with an
  empty kernel cache (the window programs are evaluated in NumPy — the same bits — while
  their C is compiled in the background; "build" is the derivation and code generation, and
  the compilation still running after the cold solve is waited for, not counted); warm: the
  same solve again with the compiled kernels (best of three), its iterations and the time
  per iteration; the peak resident memory of the process and the peak of the traced
  allocations during a solve;
- CasADi's Newton rootfinder (MX graph, Jacobian by AD, sparse ``qr``) on the stacked
  first-order necessary conditions of the transcription of ``_bvp_casadi.py``;
- Ipopt on the ``Opti`` transcription (exact Hessian, MUMPS): the build, the whole solve call,
  and Ipopt's own wall time.

The solutions are compared as velocities ξ_k = x_k/h of the free arrows (max |Δξ|).  The
summary checks the targets: warm ≥ 5× faster than Ipopt's own solve at every N; cold faster
than CasADi's build + solve for N ≥ 1000; time per iteration linear in N (fitted exponent);
peak memory ≤ 400 MB at N = 16000.

Run:  python benchmarks/bvp.py [--sizes 250 1000 4000 16000] [--problems rigid_body so3 se2]
      [--no-casadi] [--timeout 1800]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
HERE = pathlib.Path(__file__).resolve().parent
PROBLEMS = ("rigid_body", "so3", "se2")
SIZES = (250, 1000, 4000, 16000)
SOLVERS = ("library", "rootfinder", "ipopt")


# --- the problems ------------------------------------------------------------------------------

def _load(path: pathlib.Path, name: str):
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _rigid_body():
    return _load(ROOT / "examples" / "rigid_body_attitude.py", "rigid_body_attitude")


def _families():
    return _load(HERE / "_bvp_problems.py", "_bvp_problems")


def problem(name: str, steps: int) -> dict:
    """The system (a callable: constructing it is the derivation step), the boundary data and
    the parameters of one benchmark problem."""
    if name == "rigid_body":
        rb = _rigid_body()
        start, end = rb.boundary_data(steps)
        values = rb.parameter_values(steps)
        return {"system": rb.attitude_system, "start": start, "end": end,
                "params": [values[s] for s in rb.PARAMETERS], "h": values[rb.h]}
    fam = _families()
    h = 1.0 / steps
    if name == "so3":
        return {"system": lambda: fam.so3_system(False), "start": np.eye(3),
                "end": fam.rotation((0.6, -0.4, 0.9)), "params": [h, 1.0, 2.0, 3.0], "h": h}
    return {"system": fam.se2_system, "start": np.eye(3),
            "end": fam.pose(0.8, 0.6, np.pi / 3), "params": [h, 1.0, 1.0], "h": h}


def _guess_charts(name: str, steps: int) -> np.ndarray:
    """Cayley coordinates of the free arrows of the library's default guess."""
    import symgroupoid as sg
    from symgroupoid.runtime._bvp import interpolate_arrows

    spec = problem(name, steps)
    if name == "rigid_body":
        (_, R1), (RN1, _) = spec["start"], spec["end"]
        G = sg.SO3("W")
        arrows = interpolate_arrows(G, (R1.T @ RN1).ravel(), steps - 2)
    else:
        G = spec["system"]().groupoid
        arrows = interpolate_arrows(G, G.arrow_between(spec["start"], spec["end"]), steps)
    return np.array([G.fibre_chart_inverse(a) for a in arrows])


# --- the workers (one process each) ------------------------------------------------------------

def _peak_rss_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def worker_library(name: str, steps: int, out: pathlib.Path) -> dict:
    """Cold (derive + build + solve in a fresh process with an empty kernel cache), then warm."""
    import tracemalloc

    import symgroupoid as sg
    from symgroupoid.runtime._bvp import cost_kernel, window_kernel
    from symgroupoid.runtime._programs import wait_for_kernels

    spec = problem(name, steps)
    t0 = time.perf_counter()
    system = spec["system"]()
    t1 = time.perf_counter()
    window_kernel(system)
    cost_kernel(system)
    t2 = time.perf_counter()

    def solve():
        return sg.solve_boundary_value(system, spec["start"], spec["end"], steps,
                                       params=spec["params"])

    sol = solve()
    t3 = time.perf_counter()
    wait_for_kernels()  # the window kernels built in the background during the cold solve
    t4 = time.perf_counter()
    warm = []
    for _ in range(3):
        t = time.perf_counter()
        sol = solve()
        warm.append(time.perf_counter() - t)
    tracemalloc.start()
    solve()
    traced = tracemalloc.get_traced_memory()[1] / 2 ** 20
    tracemalloc.stop()
    charts = sol.controls[1:-1] if name == "rigid_body" else sol.controls
    np.save(out, charts / spec["h"])
    return {"derive": t1 - t0, "build": t2 - t1, "first_solve": t3 - t2, "cold": t3 - t0,
            "background": t4 - t3,
            "warm": min(warm), "iterations": sol.iterations, "method": sol.method,
            "per_iteration": min(warm) / max(sol.iterations, 1), "residual": sol.residual_norm,
            "cost": sol.cost, "kind": sol.kind, "peak_rss_mb": _peak_rss_mb(),
            "traced_mb": traced, "success": True}


def worker_casadi(solver: str, name: str, steps: int, out: pathlib.Path) -> dict:
    casadi_models = _load(HERE / "_bvp_casadi.py", "_bvp_casadi")
    spec = problem(name, steps)
    chart = _guess_charts(name, steps)
    t0 = time.perf_counter()
    if name == "rigid_body":
        tr = casadi_models.rigid_body(spec["start"], spec["end"], spec["params"], chart)
    else:
        kind = "so3_free" if name == "so3" else name
        tr = casadi_models.first_order(kind, spec["end"], spec["params"], chart)
    t_problem = time.perf_counter() - t0
    run = casadi_models.solve_ipopt if solver == "ipopt" else casadi_models.solve_rootfinder
    result = run(tr)
    np.save(out, result.chart / spec["h"])
    return {"build": result.build_seconds + t_problem, "solve": result.solve_seconds,
            "solver": result.solver_seconds, "iterations": result.iterations,
            "success": bool(result.success), "status": result.status, "cost": result.cost,
            "total": result.build_seconds + t_problem + result.solve_seconds,
            "peak_rss_mb": _peak_rss_mb()}


def _worker(argv: list[str]) -> None:
    solver, name, steps, out = argv[0], argv[1], int(argv[2]), pathlib.Path(argv[3])
    if solver == "library":
        result = worker_library(name, steps, out)
    else:
        result = worker_casadi(solver, name, steps, out)
    print("RESULT " + json.dumps(result))


def run_worker(solver: str, name: str, steps: int, workdir: pathlib.Path,
               timeout: float) -> dict:
    """One measurement in a fresh process (library: with an empty kernel cache)."""
    out = workdir / f"{solver}_{name}_{steps}.npy"
    env = dict(os.environ)
    env["SYMGROUPOID_CACHE"] = str(workdir / f"cache_{solver}_{name}_{steps}")
    try:
        proc = subprocess.run([sys.executable, __file__, "--worker", solver, name,
                               str(steps), str(out)], capture_output=True, text=True,
                              timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"success": False, "status": f"timeout after {timeout:.0f} s"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            result = json.loads(line[7:])
            result["charts"] = np.load(out)
            return result
    tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
    return {"success": False, "status": f"failed: {tail[:120]}"}


# --- the report ----------------------------------------------------------------------------------

def _agreement(a: dict, b: dict) -> float:
    if not (a.get("success") and b.get("success")):
        return float("nan")
    return float(np.abs(a["charts"] - b["charts"]).max())


def report(results: dict, sizes, names, casadi: bool) -> None:
    header = (f"{'problem':10s} {'N':>6s} | {'cold s':>7s} {'build':>6s} {'warm s':>7s} "
              f"{'it':>3s} {'ms/it':>7s} {'RSS MB':>7s} {'traced':>7s} |")
    if casadi:
        header += (f" {'root b+s':>9s} {'it':>3s} {'|Δξ|':>8s} | {'ipopt b+s':>9s} "
                   f"{'ipopt s':>8s} {'it':>4s} {'|Δξ|':>8s} | {'warm×':>6s} {'cold×':>6s}")
    print(header)
    print("-" * len(header))
    for name in names:
        for n in sizes:
            lib = results[name, n]["library"]
            if not lib.get("success"):
                print(f"{name:10s} {n:6d} | library {lib.get('status')}")
                continue
            line = (f"{name:10s} {n:6d} | {lib['cold']:7.2f} {lib['build']:6.2f} "
                    f"{lib['warm']:7.3f} {lib['iterations']:3d} "
                    f"{1e3 * lib['per_iteration']:7.1f} {lib['peak_rss_mb']:7.0f} "
                    f"{lib['traced_mb']:7.0f} |")
            if casadi:
                root, ipopt = results[name, n]["rootfinder"], results[name, n]["ipopt"]
                line += _casadi_columns(lib, root, ipopt)
            print(line)


def _casadi_columns(lib: dict, root: dict, ipopt: dict) -> str:
    def total(r):
        return f"{r['total']:9.2f}" if r.get("success") else f"{'FAIL':>9s}"

    out = (f" {total(root)} {root.get('iterations', -1):3d} {_agreement(lib, root):8.1e} |"
           f" {total(ipopt)} {ipopt.get('solver', float('nan')):8.2f} "
           f"{ipopt.get('iterations', -1):4d} {_agreement(lib, ipopt):8.1e} |")
    warm = ipopt.get("solver", float("nan")) / lib["warm"] if ipopt.get("success") else np.nan
    peers = [r["total"] for r in (root, ipopt) if r.get("success")]
    cold = min(peers) / lib["cold"] if peers else float("nan")
    return out + f" {warm:6.1f} {cold:6.1f}"


def targets(results: dict, sizes, names, casadi: bool) -> None:
    print("\nTargets")
    for name in names:
        libs = [results[name, n]["library"] for n in sizes]
        ok = [r for r in libs if r.get("success")]
        if len(ok) >= 2:
            ns = [n for n, r in zip(sizes, libs) if r.get("success")]
            slope = np.polyfit(np.log(ns), np.log([r["per_iteration"] for r in ok]), 1)[0]
            print(f"  {name}: time per iteration ∝ N^{slope:.2f} over N = {ns[0]} … {ns[-1]} "
                  f"({'linear: met' if slope < 1.15 else 'NOT linear'})")
        if 16000 in sizes and results[name, 16000]["library"].get("success"):
            rss = results[name, 16000]["library"]["peak_rss_mb"]
            print(f"  {name}: peak RSS at N = 16000 {rss:.0f} MB "
                  f"({'≤ 400 MB: met' if rss <= 400 else '> 400 MB: MISSED'})")
        if not casadi:
            continue
        for n in sizes:
            lib, ipopt = results[name, n]["library"], results[name, n]["ipopt"]
            root = results[name, n]["rootfinder"]
            if lib.get("success") and ipopt.get("success"):
                ratio = ipopt["solver"] / lib["warm"]
                print(f"  {name} N = {n}: warm {ratio:.1f}× faster than Ipopt's solve "
                      f"({'met' if ratio >= 5 else 'MISSED'})")
            peers = [r["total"] for r in (root, ipopt) if r.get("success")]
            if n >= 1000 and lib.get("success") and peers:
                ratio = min(peers) / lib["cold"]
                print(f"  {name} N = {n}: cold {ratio:.2f}× CasADi's fastest build + solve "
                      f"({'met' if ratio > 1 else 'MISSED'})")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--worker":
        _worker(argv[1:])
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--problems", nargs="+", default=list(PROBLEMS), choices=PROBLEMS)
    parser.add_argument("--no-casadi", action="store_true", help="the library only")
    parser.add_argument("--timeout", type=float, default=1800.0,
                        help="seconds per solver run (default 1800)")
    args = parser.parse_args(argv)
    casadi = not args.no_casadi
    if casadi:
        try:
            import casadi as _  # noqa: F401
        except ImportError:
            print("CasADi is not installed (pip install '.[bench]'): the library only")
            casadi = False
    solvers = SOLVERS if casadi else ("library",)
    results: dict = {}
    with tempfile.TemporaryDirectory(prefix="symgroupoid-bvp-bench-") as tmp:
        workdir = pathlib.Path(tmp)
        for name in args.problems:
            for n in args.sizes:
                results[name, n] = {}
                for solver in solvers:
                    t = time.perf_counter()
                    results[name, n][solver] = run_worker(solver, name, n, workdir,
                                                          args.timeout)
                    r = results[name, n][solver]
                    print(f"  [{name} N = {n} {solver}: {time.perf_counter() - t:.1f} s, "
                          f"{'ok' if r.get('success') else r.get('status')}]", flush=True)
    print()
    report(results, args.sizes, args.problems, casadi)
    targets(results, args.sizes, args.problems, casadi)
    return 0


if __name__ == "__main__":
    sys.exit(main())
