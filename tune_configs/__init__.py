"""Data only: the shipped experiment configs and the paper's plans (`rllib_conv.tune_configs` once installed; see `rllib_conv.common.resources`)."""
