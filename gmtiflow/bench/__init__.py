"""The GMTI tracker benchmark suite (docs/benchmark.md).

* :mod:`.scenarios`: the challenge scenarios shipped as ``conf/experiment/challenge/*.yaml``;
* :mod:`.challenges`: checks that a scenario's challenge occurred in a run;
* :mod:`.collect`, :mod:`.stats`, :mod:`.verdict`: read a benchmark sweep and compare trackers
  per scenario paired by seed; :mod:`.outputs` writes the table (CSV, Markdown) and the
  comparison PDF (:mod:`.pdf`);
* :mod:`.cli`: ``gmtiflow-bench``, one command for trackers × scenarios × seeds.
"""
