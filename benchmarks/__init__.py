"""Benchmarks: scripts that measure the library and write `benchmarks/results/<name>.json`.

Each script runs as a module from the repository root, `python -m benchmarks.<name> --help`;
`benchmarks/README.md` names them, what each measures and its latest result file.
Not part of the wheel: the scripts import `rllib_conv` (and `analysis`) from the checkout.
"""
