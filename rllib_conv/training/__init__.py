"""Training infrastructure shared by every pipeline: configs, the RLlib builder, the Tune loop, checkpoints, evaluation.

- `settings`, `experiment`: the typed ego experiment (`ExperimentConfig`) and its parts.
- `ego_setup`, `algorithm`: an experiment resolved against its population, then an RLlib `PPOConfig`.
- `trainable`, `tuning`, `callbacks`: the one Tune Trainable base class, `fit` (the one
  training loop), its progress output and result-file hygiene.
- `checkpoints`, `rng_state`, `weights`: sealed checkpoints, exact resumes, weights moved by hand.
- `evaluate`, `marginals`: returns with a partner and the distance to the true marginals.
- `maml`, `head_pick`: first-order MAML outer steps; picking the head an adaptation starts from.

Entry points built on these are in `rllib_conv.pipelines`.
"""
