"""Hydra callback of the benchmark configs: the verdict at the end of the multirun.

``conf/bench/suite.yaml`` registers it as ``hydra.callbacks.bench_verdict`` with the reference
tracker as its argument (``hydra.callbacks.bench_verdict.reference=<tracker>``).  Hydra calls
``on_multirun_end`` once in the launching process when every job succeeded; after a sweep with
failed jobs build the same outputs with ``gmtiflow-bench report <sweep dir>``.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, Optional

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

log = logging.getLogger(__name__)


class BenchVerdict(Callback):
    def __init__(self, reference: Optional[str] = None) -> None:
        self.reference = reference

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(OmegaConf.select(config, "hydra.sweep.dir"))
        try:
            from gmtiflow.bench.outputs import build
            paths = build([sweep_dir], sweep_dir, reference=self.reference)
            log.info("benchmark verdict: %s", ", ".join(str(p) for p in paths.values()))
        except Exception as exc:   # never turn a finished benchmark into a failure
            log.error("benchmark verdict not written (%s); run `gmtiflow-bench report %s`",
                      exc, sweep_dir)
