"""The benchmark's verdict: per scenario and metric, each tracker's mean and 95 % interval over
seeds, and its paired difference to the reference tracker; as CSV, Markdown and a PDF.

:func:`compare` turns job records (:mod:`gmtiflow.bench.collect`) into :class:`Cell` rows;
:func:`write_outputs` writes ``bench_results.csv`` (one row per scenario × metric × tracker),
``bench_results.md`` (a summary of the headline metric per scenario, then one table per
scenario); :mod:`.outputs` writes them with ``bench_report.pdf`` (:mod:`.pdf`).  Statistics:
:mod:`.stats`.
"""
from __future__ import annotations

import csv
import io
import logging
import math
from dataclasses import dataclass, field
from typing import Dict, Iterable, List, Optional, Sequence

from . import stats
from .collect import JobRecord
from .metrics import METRICS, headline, scenario_metrics
from .scenarios import SCENARIOS

log = logging.getLogger(__name__)

MARK = {"better": "▲ better", "worse": "▼ worse", "tie": "= n.d."}


@dataclass
class Cell:
    scenario: str
    metric: str
    tracker: str
    by_seed: Dict[int, float]
    est: stats.Estimate
    delta: Optional[stats.Estimate] = None     # vs the reference (None for the reference)
    verdict: str = ""


@dataclass
class Comparison:
    reference: str
    trackers: List[str]
    scenarios: List[str]
    cells: List[Cell]
    records: List[JobRecord] = field(default_factory=list)

    def cell(self, scenario: str, metric: str, tracker: str) -> Optional[Cell]:
        for c in self.cells:
            if (c.scenario, c.metric, c.tracker) == (scenario, metric, tracker):
                return c
        return None

    @property
    def failed(self) -> List[JobRecord]:
        return [r for r in self.records if not r.ok]

    @property
    def seeds(self) -> List[int]:
        return sorted({r.seed for r in self.records if r.ok})


def _order(names: Iterable[str], first: Sequence[str]) -> List[str]:
    names = set(names)
    return [n for n in first if n in names] + sorted(names - set(first))


def compare(records: List[JobRecord], reference: Optional[str] = None) -> Comparison:
    """Cells for every (scenario, metric of that scenario, tracker) with any value."""
    ok = [r for r in records if r.ok]
    trackers = sorted({r.tracker for r in ok})
    if reference is None:
        reference = "nn_kalman" if "nn_kalman" in trackers else (trackers[0] if trackers else "")
    elif trackers and reference not in trackers:
        raise ValueError(f"reference tracker {reference!r} is not in the results "
                         f"({', '.join(trackers)})")
    trackers = _order(trackers, [reference])
    scenarios = _order({r.scenario for r in ok}, SCENARIOS)
    table: Dict[tuple, Dict[int, float]] = {}
    for r in ok:
        for metric in scenario_metrics(r.scenario):
            seeds = table.setdefault((r.scenario, metric, r.tracker), {})
            if r.seed in seeds:
                log.warning("%s: a second result for %s / %s / seed %d replaces the first",
                            r.dir, r.scenario, r.tracker, r.seed)
            seeds[r.seed] = float(r.values.get(metric, math.nan))
    cells = []
    for scenario in scenarios:
        for metric in scenario_metrics(scenario):
            ref = table.get((scenario, metric, reference))
            for tracker in trackers:
                by_seed = table.get((scenario, metric, tracker))
                if by_seed is None:
                    continue
                est = stats.clip(stats.estimate(list(by_seed.values())), *METRICS[metric].bounds)
                cell = Cell(scenario, metric, tracker, by_seed, est)
                if tracker != reference and ref is not None:
                    cell.delta = stats.paired(by_seed, ref)
                    cell.verdict = stats.verdict(cell.delta, METRICS[metric].higher_is_better)
                cells.append(cell)
    return Comparison(reference, trackers, scenarios, cells, records)


# ------------------------------------------------------------------------------ formatting

def fmt(v: float) -> str:
    if v is None or not math.isfinite(v):
        return "–"
    a = abs(v)
    if a >= 100:
        return f"{v:.0f}"
    if a >= 10:
        return f"{v:.1f}"
    return f"{v:.2f}"


def fmt_est(e: stats.Estimate) -> str:
    if e.n == 0:
        return "–"
    if not math.isfinite(e.low):
        return f"{fmt(e.mean)} (n={e.n})"
    return f"{fmt(e.mean)} [{fmt(e.low)}, {fmt(e.high)}]"


def metric_title(name: str) -> str:
    m = METRICS[name]
    unit = f" ({m.unit})" if m.unit else ""
    return f"{m.label}{unit}, {'higher' if m.higher_is_better else 'lower'} is better"


def to_csv(comp: Comparison) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["scenario", "metric", "unit", "higher_is_better", "tracker", "n_seeds", "mean",
                "ci95_low", "ci95_high", "reference", "delta_mean", "delta_ci95_low",
                "delta_ci95_high", "verdict", "seeds", "values"])
    for c in comp.cells:
        m = METRICS[c.metric]
        d = c.delta or stats.Estimate(math.nan, math.nan, math.nan, 0)
        seeds = sorted(c.by_seed)
        w.writerow([c.scenario, c.metric, m.unit, int(m.higher_is_better), c.tracker, c.est.n,
                    repr(c.est.mean), repr(c.est.low), repr(c.est.high), comp.reference,
                    repr(d.mean), repr(d.low), repr(d.high), c.verdict or "reference",
                    " ".join(map(str, seeds)), " ".join(repr(c.by_seed[s]) for s in seeds)])
    return buf.getvalue()


def _md_row(cells: Sequence[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def to_markdown(comp: Comparison, title: str = "Tracker benchmark") -> str:
    others = [t for t in comp.trackers if t != comp.reference]
    seeds = comp.seeds
    lines = [f"# {title}", "",
             f"{len(comp.records) - len(comp.failed)} jobs completed, {len(comp.failed)} "
             f"failed; seeds {', '.join(map(str, seeds)) or '–'}; reference tracker "
             f"`{comp.reference}`.  Cells: mean [95 % interval] over seeds; Δ: mean paired "
             f"difference (tracker − reference, same seed) [95 % interval]; ▲ better / ▼ worse "
             f"when the paired interval excludes 0, = n.d. (not distinguishable) otherwise.", "",
             "## Summary: each scenario's challenge metric", ""]
    head = ["scenario", "challenge metric", f"`{comp.reference}`"]
    for t in others:
        head += [f"`{t}`", f"Δ `{t}`"]
    lines += [_md_row(head), _md_row(["---"] * len(head))]
    for s in comp.scenarios:
        metric = headline(s)
        row = [s, metric_title(metric)]
        ref = comp.cell(s, metric, comp.reference)
        row.append(fmt_est(ref.est) if ref else "–")
        for t in others:
            c = comp.cell(s, metric, t)
            row += [fmt_est(c.est) if c else "–",
                    f"{fmt_est(c.delta)} {MARK[c.verdict]}" if c and c.delta else "–"]
        lines.append(_md_row(row))
    for s in comp.scenarios:
        lines += ["", f"## {s}", "", _md_row(["metric", *head[2:]]),
                  _md_row(["---"] * (len(head) - 1))]
        for metric in scenario_metrics(s):
            ref = comp.cell(s, metric, comp.reference)
            row = [metric_title(metric), fmt_est(ref.est) if ref else "–"]
            for t in others:
                c = comp.cell(s, metric, t)
                row += [fmt_est(c.est) if c else "–",
                        f"{fmt_est(c.delta)} {MARK[c.verdict]}" if c and c.delta else "–"]
            lines.append(_md_row(row))
    if comp.failed:
        lines += ["", "## Failed jobs", ""]
        lines += [f"- `{r.dir}`: {r.error}" for r in comp.failed]
    return "\n".join(lines) + "\n"
