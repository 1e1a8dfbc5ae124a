"""The packed-replica machinery: K egos trained as one, their weights stacked and run as batched matmuls.

None of this is in the paper; it makes training fast without changing a number. A packed
ego equals K plain egos (`TaskModule` + one `PartnerHeadModule` per partner, the paper's
modules in `rllib_conv.modules`) weight for weight:

- `ego_stack`: `EgoStack`, every replica's task module and heads as stacked tensors
  (initialised by copying freshly built plain modules, read and written under their names).
- `stacked_multi`: `StackedEgoMultiRLModule` (what trains), `HeadView` (one replica's head,
  what an agent maps to) and `StackedOutput` (what one training forward gives the learner).
"""
