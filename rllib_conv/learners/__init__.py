"""Learners: PPO with the paper's marginal regulariser and real freezing.

The paper's loss, readable on its own:

- `regulariser`: `marginal_distance`, the marginal regulariser D.
- `ppo_loss`: PPO's clipped surrogate loss, RLlib's arithmetic.
- `marginal_learner`: `MarginalPPOLearner`, PPO + lam * D (+ the head penalty) and freezing.
- `head_penalty`: `head_size`, the head penalty H (`head_l2`, beyond the paper).
- `population_entropy`: MEP's bonus, the entropy of several self-play pairs' mean policy (beyond the paper).
- `trajectory_diversity`: TrajeDi's bonus, the JSD of several self-play pairs' trajectory distributions (beyond the paper).
- `settings`: `LearnerSettings`, what the learner reads from `learner_config_dict` (light: no torch, no Ray).
- `minibatches`: RLlib's minibatch order, as row indices.
- `drop_bootstrap_rows`: the learner connector piece that drops PPO's bootstrap rows after GAE.

`packed/` holds the speed machinery (the fused minibatch loop and Adam step, the batched
sampler's `Rollout`), which changes no number.
"""
