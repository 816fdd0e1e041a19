def build_sweep_report(*a, **k): raise NotImplementedError
