"""The benchmark's comparison PDF: which tracker is better in which scenario.

Page 1: the summary matrix, one row per scenario (its challenge metric) and one column per
tracker, each cell the mean [95 % interval] over seeds, coloured by the paired comparison with
the reference tracker (green better, red worse, grey not distinguishable; the reference
column is white).  Then one page per scenario: one bar panel per metric, a bar per tracker
with its 95 % interval, and the paired verdict against the reference above each bar.  A last
page lists failed jobs.  Built with :class:`matplotlib.figure.Figure` (no pyplot), like the
run and sweep reports.
"""
from __future__ import annotations

import math
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_pdf import PdfPages

from gmtiflow import __version__
from gmtiflow.formats import atomic_path
from gmtiflow.report.figures import new_figure

from .metrics import METRICS, headline, scenario_metrics
from .scenarios import CHALLENGE_TEXT
from .verdict import Comparison, fmt_est, metric_title

COLOURS = {"better": "#a6dba0", "worse": "#f4a582", "tie": "#e0e0e0", "": "#ffffff"}
SYMBOL = {"better": "▲", "worse": "▼", "tie": "=", "": ""}
PALETTE = ["#4575b4", "#d73027", "#1a9850", "#984ea3", "#ff7f00", "#a65628", "#f781bf",
           "#666666"]


def _summary_page(comp: Comparison):
    fig = new_figure()
    fig.text(0.5, 0.96, "GMTI tracker benchmark: which tracker is better where", ha="center",
             fontsize=15, weight="bold")
    seeds = comp.seeds
    fig.text(0.5, 0.925, f"{len(comp.scenarios)} scenarios × {len(comp.trackers)} trackers × "
             f"{len(seeds)} seeds ({', '.join(map(str, seeds))}); reference `{comp.reference}`; "
             f"{len(comp.failed)} failed job(s).  gmtiflow {__version__}, "
             f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC", ha="center", fontsize=8.5)
    ax = fig.add_axes([0.02, 0.1, 0.96, 0.78])
    ax.axis("off")
    header = ["scenario", "challenge metric"] + list(comp.trackers)
    rows, colours = [], []
    for s in comp.scenarios:
        metric = headline(s)
        row, col = [s, metric_title(metric)], ["#ffffff", "#ffffff"]
        for t in comp.trackers:
            c = comp.cell(s, metric, t)
            if c is None:
                row.append("–")
                col.append("#ffffff")
                continue
            row.append(f"{SYMBOL[c.verdict]} {fmt_est(c.est)}".strip())
            col.append(COLOURS[c.verdict])
        rows.append(row)
        colours.append(col)
    if rows:
        # the metric label gets the room it needs; the trackers share the rest
        label_w, scen_w = 0.24, 0.09
        each = (1.0 - label_w - scen_w) / max(len(comp.trackers), 1)
        table = ax.table(cellText=rows, cellColours=colours, colLabels=header, loc="upper center",
                         cellLoc="center",
                         colWidths=[scen_w, label_w] + [each] * len(comp.trackers))
        table.auto_set_font_size(False)
        table.set_fontsize(8)
        table.scale(1.0, 1.6)
        for (r, c), cell in table.get_celld().items():
            if r == 0:
                cell.set_text_props(weight="bold")
    fig.text(0.02, 0.04, "Cells: mean [95 % interval] over seeds.  Colour and symbol: the paired "
             "(same-seed) difference to the reference tracker; ▲ green = better, ▼ red = worse "
             "(95 % interval of the difference excludes 0), = grey = not distinguishable with "
             "these seeds.\nEach scenario page shows all its metrics.", fontsize=8, va="bottom")
    return fig


def _bar_panel(ax, comp: Comparison, scenario: str, metric: str):
    trackers = comp.trackers
    x = np.arange(len(trackers))
    for i, t in enumerate(trackers):
        c = comp.cell(scenario, metric, t)
        if c is None or c.est.n == 0:
            ax.text(i, 0, "no value", ha="center", va="bottom", fontsize=7, rotation=90)
            continue
        err = None
        if math.isfinite(c.est.low):
            err = [[c.est.mean - c.est.low], [c.est.high - c.est.mean]]
        ax.bar(i, c.est.mean, color=PALETTE[i % len(PALETTE)], alpha=0.85, yerr=err,
               capsize=4, ecolor="black")
        vals = np.array(list(c.by_seed.values()), float)
        ax.plot(np.full(vals.size, i) + np.linspace(-0.15, 0.15, vals.size), vals, ".",
                color="black", ms=3, alpha=0.6)
        if c.verdict:
            top = c.est.high if math.isfinite(c.est.high) else c.est.mean
            ax.annotate(SYMBOL[c.verdict], (i, top), textcoords="offset points", xytext=(0, 3),
                        ha="center", fontsize=11,
                        color={"better": "#1a9850", "worse": "#d73027"}.get(c.verdict, "grey"))
    ax.set_xticks(x)
    ax.set_xticklabels(trackers, rotation=20, ha="right", fontsize=7)
    m = METRICS[metric]
    ax.set_title(f"{m.label}{' (' + m.unit + ')' if m.unit else ''}\n"
                 f"{'↑' if m.higher_is_better else '↓'} "
                 f"{'higher' if m.higher_is_better else 'lower'} is better", fontsize=8.5)
    ax.tick_params(axis="y", labelsize=7)
    ax.margins(y=0.15)
    ax.grid(axis="y", alpha=0.3)


def _scenario_page(comp: Comparison, scenario: str):
    fig = new_figure()
    metrics = scenario_metrics(scenario)
    ncol = 4
    nrow = int(math.ceil(len(metrics) / ncol))
    fig.suptitle(f"{scenario}: {CHALLENGE_TEXT.get(scenario, '')}", fontsize=12, weight="bold")
    fig.text(0.5, 0.925, f"bars: mean over seeds with 95 % interval, dots: single seeds; "
             f"▲/▼/= paired vs `{comp.reference}`.  First panels: the challenge metrics.",
             ha="center", fontsize=8)
    for k, metric in enumerate(metrics):
        ax = fig.add_subplot(nrow, ncol, k + 1)
        _bar_panel(ax, comp, scenario, metric)
    fig.subplots_adjust(left=0.06, right=0.98, top=0.84, bottom=0.12, hspace=0.75, wspace=0.35)
    return fig


def _failed_page(comp: Comparison):
    fig = new_figure()
    fig.text(0.02, 0.95, f"Failed jobs ({len(comp.failed)})", fontsize=13, weight="bold",
             va="top")
    text = "\n".join(f"{r.dir}: {r.error}"[:160] for r in comp.failed[:45])
    fig.text(0.02, 0.9, text, fontsize=7, va="top", family="monospace")
    return fig


def build_pdf(comp: Comparison, path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        with PdfPages(tmp) as pdf:
            pdf.savefig(_summary_page(comp))
            for scenario in comp.scenarios:
                pdf.savefig(_scenario_page(comp, scenario))
            if comp.failed:
                pdf.savefig(_failed_page(comp))
    return path
