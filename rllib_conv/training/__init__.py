"""Training infrastructure shared by every pipeline: configs, the RLlib builder, the Tune loop, checkpoints, evaluation.

- `settings`, `experiment`: the typed ego experiment (`ExperimentConfig`) and its parts.
- `ego_setup`, `algorithm`: an experiment resolved against its population, then an RLlib `PPOConfig`.
- `trainable`, `tuning`, `callbacks`: the one Tune Trainable base class, `fit` (the one
  training loop), its progress output and result-file hygiene.
- `stage`, `packs`: the one stage runner (many configs as one Tune run) and how its units pack into trials.
- `checkpoints`, `rng_state`, `weights`: sealed checkpoints, exact resumes, weights moved by hand.
- `evaluate`, `marginal_distance`: returns with a partner and the distance to the true marginals.
- `maml`: first-order MAML outer steps.

Adapting to a new partner (head pick, convention posterior, guard) is `rllib_conv.adaptation`.

Entry points built on these are in `rllib_conv.pipelines`.
"""
