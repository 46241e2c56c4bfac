"""Times `Robot.fk_many` on 10,000 configurations of the robots `benches/fk_many.rs` times in
Rust (same configurations: the middle of each joint's range ± 0.05), and a Python loop of
`Robot.fk` for contrast. Run from the repository's root with the package installed:

    python python/bench/fk_many.py
"""

import time
import warnings

import numpy as np

import armcomp

N = 10_000


def configurations(robot):
    """The middle of each joint's range (0 without limits) ± 0.05, like the Rust bench."""
    limits = robot.joint_limits
    middle = np.where(np.isfinite(limits).all(axis=1), limits.mean(axis=1), 0.0)
    return np.random.default_rng(1).uniform(-0.05, 0.05, (N, robot.nq)) + middle


def best_of(repeats, f):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return min(times), float(np.median(times))


def main():
    warnings.simplefilter("ignore")
    for name in ["talos-left-arm", "industrial-6dof-truth"]:
        robot = armcomp.Robot.load(f"robots/{name}.toml")
        q = configurations(robot)
        robot.fk_many(q)
        best, median = best_of(20, lambda: robot.fk_many(q))
        loop_best, _ = best_of(3, lambda: [robot.fk(row) for row in q[:1000]])
        print(
            f"{name:24} fk_many: {best / N * 1e9:7.1f} ns per configuration (best of 20; median "
            f"{median / N * 1e9:.1f}); Python loop of fk: {loop_best / 1000 * 1e9:7.1f} ns"
        )


if __name__ == "__main__":
    main()
