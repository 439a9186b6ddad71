"""Run a floe campaign on a Slurm cluster: Dask workers as Slurm jobs (dask-jobqueue),
``gcs campaign --dask tcp://...`` pointed at their scheduler.

On the cluster's login node, in the Python environment floe is installed in (the workers
must run the same floe version as the driver; ``floe_version`` in runs.parquet records it):

    pip install dask-jobqueue
    python campaigns/dask-slurm.py --jobs 4 --cores 16 --memory 32GB --walltime 02:00:00 \\
        --queue compute --account my-project \\
        -- campaigns/objective-tau.yaml --out out/objective-tau
    gcs campaign report out/objective-tau

What it does, step by step (copy these lines into your own script if you prefer):

1. ``SLURMCluster(cores=16, processes=16, memory="32GB", walltime="02:00:00", ...)``:
   each Slurm job is one node share running 16 single-threaded worker processes (a run is
   CPU-bound Python, one process per core; ``OPENBLAS_NUM_THREADS=1`` in every job).
   ``job_script_prologue`` activates this environment in the job (``--venv``).
2. ``cluster.scale(jobs=4)`` submits four jobs (``sbatch``; ``squeue -u $USER`` shows them).
3. It prints the scheduler's address (``tcp://10.1.2.3:8786``) and the job script.
4. It waits for the first worker, then runs ``gcs campaign CAMPAIGN.yaml --out DIR --dask
   tcp://...`` (everything after ``--``): the driver stays here and writes the Parquet
   files; the workers only simulate (a run's scenario travels with it, so the scenario
   files need not be on the nodes).
5. It closes the cluster (``scancel``) when the campaign ends or on Ctrl-C; an interrupted
   campaign resumes where it stopped when run again with the same ``--out``.

``--print-only`` starts the cluster, prints the address and waits for Ctrl-C, so you can
run ``gcs campaign ... --dask tcp://...`` yourself from another shell on the login node.

Kubernetes instead of Slurm: dask-kubernetes' operator (``pip install dask-kubernetes``, the
Dask operator installed in the cluster) starts the same kind of cluster from an image that
holds floe::

    from dask_kubernetes.operator import KubeCluster
    cluster = KubeCluster(name="floe", image="registry.example/floe:0.1.0", n_workers=16,
                          env={"OPENBLAS_NUM_THREADS": "1"},
                          resources={"requests": {"cpu": "1", "memory": "2Gi"},
                                     "limits": {"cpu": "1", "memory": "2Gi"}})
    print(cluster.scheduler_address)   # then: gcs campaign ... --dask <that address>

Run the driver inside the Kubernetes cluster (a pod), or from outside through the port
forward KubeCluster opens to the scheduler; the worker image must hold the driver's floe
version.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description="Start Dask workers as Slurm jobs and run gcs campaign on them.",
        epilog="Everything after -- is passed to gcs campaign (CAMPAIGN.yaml --out DIR ...).",
    )
    parser.add_argument("--jobs", type=int, default=2, help="Slurm jobs (default 2)")
    parser.add_argument("--cores", type=int, default=16, help="cores per job (default 16)")
    parser.add_argument("--memory", default="32GB", help="memory per job (default 32GB)")
    parser.add_argument("--walltime", default="02:00:00", help="per job (default 02:00:00)")
    parser.add_argument("--queue", default=None, help="Slurm partition (sbatch -p)")
    parser.add_argument("--account", default=None, help="Slurm account (sbatch -A)")
    parser.add_argument(
        "--interface", default=None, help="network interface of the nodes (e.g. ib0)"
    )
    parser.add_argument(
        "--venv",
        default=os.environ.get("VIRTUAL_ENV"),
        help="environment the jobs activate (default: this one, $VIRTUAL_ENV)",
    )
    parser.add_argument(
        "--print-only",
        action="store_true",
        help="start the cluster, print its address, wait for Ctrl-C",
    )
    parser.add_argument("campaign", nargs=argparse.REMAINDER, help="-- CAMPAIGN.yaml --out DIR")
    return parser


def main() -> int:
    args = _parser().parse_args()
    campaign = [a for a in args.campaign if a != "--"]
    if not campaign and not args.print_only:
        print("dask-slurm: give the campaign after --: -- CAMPAIGN.yaml --out DIR", file=sys.stderr)
        return 2
    try:
        from dask.distributed import Client
        from dask_jobqueue import SLURMCluster
    except ImportError:
        print("dask-slurm: needs dask-jobqueue (pip install dask-jobqueue)", file=sys.stderr)
        return 2
    prologue = ["export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1"]
    if args.venv:
        prologue.append(f"source {args.venv}/bin/activate")
    cluster = SLURMCluster(
        cores=args.cores,
        processes=args.cores,  # one single-threaded worker process per core
        memory=args.memory,
        walltime=args.walltime,
        queue=args.queue,
        account=args.account,
        interface=args.interface,  # for the workers and the scheduler
        job_script_prologue=prologue,  # dask-jobqueue < 0.8.2 calls it env_extra
    )
    try:
        cluster.scale(jobs=args.jobs)
        address = cluster.scheduler_address
        print(f"scheduler: {address}  (dashboard {cluster.dashboard_link})", flush=True)
        print(cluster.job_script(), flush=True)
        if args.print_only:
            print(f"run: gcs campaign CAMPAIGN.yaml --out DIR --dask {address}; Ctrl-C ends")
            while True:
                time.sleep(60)
        with Client(cluster) as client:
            print("waiting for the first worker (the jobs are queued)...", flush=True)
            client.wait_for_workers(1)
        command = [sys.executable, "-m", "groundstation.cli", "campaign", *campaign]
        command += ["--dask", address]
        print(" ".join(command), flush=True)
        return subprocess.run(command, check=False).returncode
    except KeyboardInterrupt:
        return 130
    finally:
        cluster.close()


if __name__ == "__main__":
    sys.exit(main())
