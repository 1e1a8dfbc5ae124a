"""Data only: the paper's user-study table (`rllib_conv.data` once installed; see `rllib_conv.common.resources`)."""
