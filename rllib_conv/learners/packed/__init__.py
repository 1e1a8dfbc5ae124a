"""The learner's speed machinery: one minibatch loop and one optimizer step for every packed replica.

None of this is in the paper (its loss is `ppo_loss` plus the regulariser of
`rllib_conv.learners.regulariser`); each piece is checked against RLlib's own path:

- `fused_update`: `FusedUpdateLearner`, PPO's update as one loop over batched minibatches of
  every replica and head (RLlib's loop is the reference of `tests/learners/test_fused_update.py`).
- `fused_step`: `FusedAdamStep`, per-replica gradient clipping and one fused Adam call.
- `rollout`: `Rollout`, the rows the batched sampler hands the learner, and their train batch.
"""
