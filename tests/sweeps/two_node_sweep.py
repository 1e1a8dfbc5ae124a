"""Start a 2-node Ray cluster on loopback, run `rllib-conv sweep` on it, shut the cluster down.

Usage: python two_node_sweep.py CONFIG STORAGE [SWEEP ARGS...]; exits with the sweep's status.
The head offers 1 CPU; the second node 2 CPUs and the custom resource `second_node`, so a
trial asking for `run.resources: {second_node: 1}` can only run there.
"""

import subprocess
import sys

from ray.cluster_utils import Cluster

if __name__ == "__main__":
    config, storage, *extra = sys.argv[1:]
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    try:
        cluster.add_node(num_cpus=2, resources={"second_node": 2})
        cluster.wait_for_nodes()
        cmd = [
            sys.executable,
            "-m",
            "rllib_conv.cli",
            "sweep",
            config,
            "--storage",
            storage,
            "--address",
            cluster.address,
            *extra,
        ]
        status = subprocess.run(cmd).returncode
    finally:
        cluster.shutdown()
    sys.exit(status)
