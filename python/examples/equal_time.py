"""PT, BDPT and MMLT at equal time: relMSE against a converged reference as the time
budget grows, on a log-log plot (docs/python.md). Run it from anywhere:

    python python/examples/equal_time.py --scene scenes/caustic.test --out equal-time.png

LIGHTPATH_EXAMPLE_QUICK=1 makes it small and fast (the tests run it that way).
"""
import argparse
import os
from pathlib import Path

import matplotlib

matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
import matplotlib.pyplot as plt  # noqa: E402

import lightpath as lp  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def main():
    quick = os.environ.get("LIGHTPATH_EXAMPLE_QUICK") == "1"
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(REPO / "scenes/caustic.test"))
    ap.add_argument("--out", default="equal-time.png")
    args = ap.parse_args()

    scene = lp.load(args.scene)
    scene.size = (32, 24) if quick else (128, 128)
    budgets = [0.5, 1.0] if quick else [2.0, 4.0, 8.0, 16.0]
    # The reference: BDPT, long.
    reference = lp.render(scene, integrator="bdpt", spp=32 if quick else 4096, seed=999)

    fig, ax = plt.subplots(figsize=(5, 4))
    for integrator in ["pathtracer", "bdpt", "mmlt"]:
        errors = []
        for seconds in budgets:
            r = lp.render(scene, integrator=integrator, spp=1 << 30, time_limit=seconds, seed=1)
            errors.append(lp.compare(r, reference)["relmse"])
        ax.loglog(budgets, errors, marker="o", label=integrator)
        print(f"{integrator}: " + ", ".join(f"{t:g} s: {e:.4g}" for t, e in zip(budgets, errors)))
    ax.set_xlabel("seconds")
    ax.set_ylabel("relMSE against the reference")
    ax.set_title(Path(args.scene).name)
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
