"""Gain tuning for smibjax: `python -m tuning.optimize`.

- `optimize`: the command line (flags, the run folder, resume);
- `config`: the configuration (configs/default.toml: defaults and schema);
- `problem`: what a configuration builds (`build`: the start, the gain space, the
  training and validation set-up, the scenario distribution, the optimizer);
- `params`: unconstrained raw parameters <-> legal gains (`GainSpace`);
- `train`: the differentiated batch loss and the exact validation;
- `search`: the optional gradient-free warm start;
- `loop`: the training loop, its state (`TrainState`) and checkpoints;
- `outputs` and `report`: gains files, history.csv, report.md and plots;
- `resume`: how a run in a folder starts or continues, and its wall time.
"""
