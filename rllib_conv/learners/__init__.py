"""Learners: PPO with the marginal regulariser and real freezing.

- `marginal_learner`: `MarginalPPOLearner`, the regulariser `marginal_distance` and the head penalty `head_size`.
- `settings`: `LearnerSettings`, what the learner reads from `learner_config_dict` (light: no torch, no Ray).
- `drop_bootstrap_rows`: the learner connector piece that drops PPO's bootstrap rows after GAE.
- `rollout`: `Rollout`, sampled rows laid out as the learner connector lays out episodes, and their train batch.
"""
