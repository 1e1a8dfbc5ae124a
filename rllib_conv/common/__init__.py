"""The ground floor: names and file formats that every layer, and the analysis, share.

- `methods`: what each ego-training method is and supports (the method registry).
- `run_folders`: where runs, trials, stages and reproductions keep which file.
- `sealed`: folders sealed with a manifest and verified before use (checkpoints, partners).
- `atomic_files`: files written whole or not at all (write beside, then replace).
- `config_files`: experiment YAMLs with grids and `--set` overrides, validated on load.
- `user_study_table`: the user-study CSV format (the paper's table and recorded sessions).
- `resources`: the data files the package ships (configs, plans, the user-study table).

Nothing here imports torch, Ray or any other layer of `rllib_conv`, so the analysis can
read every file the pipelines write without importing training code.
"""
