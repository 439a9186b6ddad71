"""Run a floe campaign on a Slurm cluster through dask-jobqueue (docs/campaigns.md).

Run it on the cluster's login node, in the Python environment that has floe (the same
one the workers will use; it needs `pip install 'floe[campaign]' dask-jobqueue`):

    python campaign_slurm.py my-campaign.yaml results/my-campaign --jobs 4

It submits JOBS Slurm jobs, each one Dask worker process per core (one thread each: a
floe run is single-threaded), waits for the first workers, runs
`gcs campaign CAMPAIGN --out DIR --dask <this scheduler>` and releases the jobs at the
end. Interrupted (Ctrl-C, walltime), it can be started again: the campaign resumes.
Edit the SLURMCluster arguments for your site (queue, account, memory, walltime, the
network interface the workers reach the login node on, the line that activates the
environment in each job).
"""

from __future__ import annotations

import argparse
import subprocess
import sys

from dask.distributed import Client
from dask_jobqueue import SLURMCluster


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("campaign")
    parser.add_argument("out")
    parser.add_argument("--jobs", type=int, default=4, help="Slurm jobs (nodes) to use")
    parser.add_argument("--cores", type=int, default=32, help="cores per job")
    args = parser.parse_args()
    cluster = SLURMCluster(
        queue="normal",                      # your partition (#SBATCH -p)
        account="my-project",                # your account (#SBATCH -A)
        cores=args.cores,                    # cores per job ...
        processes=args.cores,                # ... one single-threaded worker per core
        memory=f"{args.cores * 2}GB",        # ~2 GB per worker is plenty for a run
        walltime="04:00:00",
        job_script_prologue=[                # dask-jobqueue < 0.8.2: env_extra=[...]
            "source $HOME/floe/.venv/bin/activate",
            "export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1",
        ],
        scheduler_options={"interface": "ib0"},  # or "eth0": what compute nodes reach
    )
    try:
        cluster.scale(jobs=args.jobs)
        with Client(cluster) as client:
            client.wait_for_workers(1, timeout=1800)  # queued jobs may take a while
        command = ["gcs", "campaign", args.campaign, "--out", args.out,
                   "--dask", cluster.scheduler_address]
        print("running:", " ".join(command), file=sys.stderr)
        return subprocess.run(command, check=False).returncode
    finally:
        cluster.close()


if __name__ == "__main__":
    sys.exit(main())
