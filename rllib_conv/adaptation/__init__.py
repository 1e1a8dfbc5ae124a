"""Adapting a trained ego to a new partner: every adapter, behind one vocabulary.

- `registry`: the adapters by name (fresh head, head pick, convention posterior, guard),
  what information each uses, the old spellings, and the checks of a combination against
  a trained ego; `rllib-conv adapt`, the play server and the report all name adapters by it.
- `head_pick`: try the fresh head and every training partner's head on the new partner; adapt from the best.
- `convention_posterior`: which known convention is the new partner following? Play by the answer.
- `fine_tune_guard`: use what fine-tuning learned only once its own rollouts show it pays.

Only the fresh head is the paper's adapter (a new partner module trained on the new
partner, task module kept); the others are this project's (docs/differences.md).
"""
