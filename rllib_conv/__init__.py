"""rllib-conv: rules vs conventions in adaptive human-AI collaboration, on Ray RLlib.

Reimplements Shih et al., "On the Critical Role of Conventions in Adaptive Human-AI
Collaboration" (ICLR 2021): a modular ego policy (one task module shared by all
partners, one partner module per partner) with a marginal regulariser.
"""

__version__ = "0.1.0"
