"""Per-step controller time: LQR vs SDRE vs Theta-D on the seed-3 spacecraft.

``python -m ocdsl.control.bench`` (wired into ``make bench``) prints, for each law, the
median / mean / 95th-percentile wall time of one controller call (u = law(t, x), SDC
evaluation included) measured in two ways:

1. ``loop``: calls at 200 states along the Theta-D closed-loop trajectory, repeated;
2. ``closed-loop``: the per-update times recorded by the 150 s simulation.

and the ratios SDRE/Theta-D and Theta-D/LQR. The seed's central claim is a Theta-D step
at least 5x faster than an SDRE step; ``main`` returns 0 when the measured median
ratio is >= 5 and 1 otherwise (so ``make bench`` shows a regression). BLAS is limited to
one thread while timing (small matrices; see :mod:`ocdsl.control.blas`).
"""
from __future__ import annotations

import argparse
import platform
import sys
import time

import numpy as np

from .blas import blas_threads

Q = np.diag([0.5] * 6 + [0.05] * 3)
R = np.eye(3)


def _setup():
    from ocdsl.models.spacecraft_wheels import paper_sdc_matrix
    from ocdsl.symbolic import sdc
    from ocdsl.symbolic.registry import build_model

    m = build_model("spacecraft_wheels", {})
    num = sdc.lambdify_sdc(sdc.given(m, paper_sdc_matrix(m), auxiliary=["hx", "hy", "hz"]))
    z0 = np.zeros(12)
    z0[:3] = np.radians(10.0)
    z0[6:9] = 0.01
    return m, num, z0


def measure(repeats: int = 5, horizon: float = 150.0, dt: float = 0.05) -> dict:
    from .lqr import LQRController
    from .sdre import SDREController
    from .simulate import simulate
    from .theta_d import ThetaDController

    m, num, z0 = _setup()
    laws = {"lqr": LQRController(num, Q, R), "sdre": SDREController(num, Q, R),
            "theta-d": ThetaDController(num, Q, R),
            "theta-d(scipy-lyap)": ThetaDController(num, Q, R, lyapunov="scipy")}
    out: dict = {"loop": {}, "closed_loop": {}}
    sims = {}
    for name in ("lqr", "sdre", "theta-d"):
        sims[name] = simulate(num.f, laws[name], z0, num.index, Q, R, horizon, dt)
        ct = sims[name].ctrl_time
        out["closed_loop"][name] = {"median": float(np.median(ct)), "mean": float(ct.mean()),
                                    "p95": float(np.percentile(ct, 95)), "calls": int(ct.size)}
    traj = sims["theta-d"]
    pick = np.linspace(0, len(traj.t) - 1, 200).astype(int)
    states = [(float(traj.t[i]), traj.z[i]) for i in pick]
    with blas_threads(1):
        for name, law in laws.items():
            law(0.0, z0)
            samples = []
            for _ in range(repeats):
                for t, z in states:
                    w0 = time.perf_counter()
                    law(t, z)
                    samples.append(time.perf_counter() - w0)
            s = np.asarray(samples)
            out["loop"][name] = {"median": float(np.median(s)), "mean": float(s.mean()),
                                 "p95": float(np.percentile(s, 95)), "calls": int(s.size)}
    for kind in ("loop", "closed_loop"):
        d = out[kind]
        d["ratio_sdre_over_theta_d"] = d["sdre"]["median"] / d["theta-d"]["median"]
        d["ratio_theta_d_over_lqr"] = d["theta-d"]["median"] / d["lqr"]["median"]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    out = measure(args.repeats)
    print(f"controller time per step (seed 3 spacecraft, 9 states; {platform.machine()}, "
          f"{platform.python_implementation()} {platform.python_version()})")
    for kind in ("loop", "closed_loop"):
        d = out[kind]
        print(f"\n[{kind}]  {'law':22s} {'median':>10s} {'mean':>10s} {'p95':>10s} {'calls':>7s}")
        for name, v in d.items():
            if isinstance(v, dict):
                print(f"         {name:22s} {v['median'] * 1e6:8.1f}us {v['mean'] * 1e6:8.1f}us "
                      f"{v['p95'] * 1e6:8.1f}us {v['calls']:7d}")
        print(f"         SDRE / Theta-D = {d['ratio_sdre_over_theta_d']:.1f}x   "
              f"Theta-D / LQR = {d['ratio_theta_d_over_lqr']:.1f}x")
    ok = out["loop"]["ratio_sdre_over_theta_d"] >= 5.0
    print(f"\nseed claim 'Theta-D at least 5x faster per step than SDRE': "
          f"{'REPRODUCED' if ok else 'NOT reproduced'} (median ratio "
          f"{out['loop']['ratio_sdre_over_theta_d']:.1f}x)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
