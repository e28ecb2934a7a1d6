"""Parameter sweeps: many runs of one scenario with parameters varied as data (``cosim sweep``).

A sweep spec (YAML) names a scenario, the tracker and estimator, the seeds, fixed overrides
and the varied parameters, each by its dotted config path (``plant.mass_kg``). The plant
(``plant.*``, the truth) and the tracker's model (``tracker.model.*``, its belief) are
separate keys, so model mismatch is their difference, stated as data.

The modules, in the order a sweep uses them:

* :mod:`cosim.sweeps.spec`: the spec as frozen dataclasses, validated; the list of runs.
* :mod:`cosim.sweeps.execute`: one run as a task (plain dict in, plain dict out) and the
  backends that run many (a process pool forked from a forkserver, or Ray).
* :mod:`cosim.sweeps.results`: the append-only ``results.jsonl``, resume, CSV/JSON and the
  Markdown summary.
* :mod:`cosim.sweeps.plots`: the heat map and metric-vs-parameter PNGs (matplotlib, Agg).
* :mod:`cosim.sweeps.driver`: :func:`run_sweep`, which ties them together for the CLI.
"""
