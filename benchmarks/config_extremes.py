"""Every numeric config leaf at its extremes: a clean error or a clean run (issue 17, item 11).

The leaves are discovered from the validated default config (so fields other people add are
swept too).  Each is set to 0, a tiny value (1e-300, or 1 for integers), a huge one (1e300, or
2^62), the largest magnitude the config accepts (``config.MAX_MAGNITUDE``) and -1.  A case
that validation (``config.validate`` + ``budget.check``) refuses is a *clean error*; an accepted
one is run on a 5 s scene (``--run``) and must end cleanly or with a GmtiflowError (*clean
run* / *clean error*); anything else (another exception, a run longer than ``--timeout``) is
*other*.

    python benchmarks/config_extremes.py                # validate all cases, run none
    python benchmarks/config_extremes.py --run all      # also run every accepted case
    python benchmarks/config_extremes.py --run 40       # run a seeded sample of 40
"""
from __future__ import annotations

import argparse
import copy
import signal
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import List, Tuple

import numpy as np

from gmtiflow import budget, config, pipeline
from gmtiflow.compose import compose
from gmtiflow.config_tree import numeric_leaves, set_leaf
from gmtiflow.errors import ConfigError, GmtiflowError

BASE = ["scene.duration_s=5", "progress=false", "export=none", "report=none",
        "cache.enabled=false"]


def extremes(value) -> List[object]:
    if isinstance(value, int):
        return [0, 1, 2 ** 62, int(config.MAX_MAGNITUDE), -1]
    return [0.0, 1e-300, 1e300, config.MAX_MAGNITUDE, -1.0]


def cases(base=None) -> List[Tuple[str, object]]:
    base = base if base is not None else compose(BASE)
    return [(leaf, v) for leaf, value in sorted(dict(numeric_leaves(base)).items())
            for v in extremes(value)]


def validate_case(base, leaf, value):
    """(config or None, error message or None): validation only."""
    cfg = copy.deepcopy(base)
    set_leaf(cfg, leaf, value)
    try:
        config.validate(cfg)
        budget.check(cfg)
    except ConfigError as exc:
        return None, str(exc)
    return cfg, None


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout()


def run_case(cfg, timeout_s: float = 120.0) -> Tuple[str, str]:
    """('clean run' | 'clean error' | 'other', detail) of one accepted config."""
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    try:
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(cfg, Path(d))
        return "clean run", ""
    except GmtiflowError as exc:
        return "clean error", str(exc)[:200]
    except _Timeout:
        return "other", f"still running after {timeout_s:g} s"
    except Exception as exc:     # noqa: BLE001 - that is what this counts
        return "other", f"{type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--run", default="0", help="accepted cases to run: a number (seeded "
                   "sample) or 'all'")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=float, default=120.0)
    args = p.parse_args(argv)
    start = time.perf_counter()
    base = compose(BASE)
    all_cases = cases(base)
    counts: Counter = Counter()
    accepted = []
    for leaf, value in all_cases:
        cfg, err = validate_case(base, leaf, value)
        if cfg is None:
            counts["clean error (validation)"] += 1
        else:
            accepted.append((leaf, value, cfg))
    if args.run == "all":
        chosen = accepted
    else:
        k = min(int(args.run), len(accepted))
        idx = np.random.default_rng(args.seed).choice(len(accepted), k, replace=False)
        chosen = [accepted[i] for i in sorted(idx)]
    counts["accepted, not run"] = len(accepted) - len(chosen)
    others = []
    for leaf, value, cfg in chosen:
        outcome, detail = run_case(cfg, args.timeout)
        counts[outcome] += 1
        if outcome == "other":
            others.append((leaf, value, detail))
    n_leaves = len({leaf for leaf, _ in all_cases})
    print(f"{n_leaves} numeric leaves, {len(all_cases)} cases, {len(accepted)} accepted, "
          f"{len(chosen)} run ({time.perf_counter() - start:.0f} s)")
    for key in ("clean error (validation)", "clean error", "clean run", "other",
                "accepted, not run"):
        print(f"  {key:26s} {counts[key]}")
    for leaf, value, detail in others:
        print(f"  OTHER {leaf}={value!r}: {detail}")
    return 1 if others else 0


if __name__ == "__main__":
    sys.exit(main())
