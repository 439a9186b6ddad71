"""``gcs campaign report DIR [--out FILE]``: the HTML report of a campaign folder.

    gcs campaign report out/paper-fig4                 # out/paper-fig4/report.html
    gcs campaign report out/paper-fig4 --out fig4.html # and fig4-series.png, ... beside it

Writes one self-contained page (every figure inline) and each figure as a PNG beside it
(``<page stem>-<figure>.png``). Exit status: 0 written, 2 a folder that is missing, empty or
unreadable, or a page that cannot be written (one line on stderr).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["run"]

_PROG = "gcs campaign report"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        allow_abbrev=False,
        prog=_PROG,
        description="Write a self-contained HTML report of a gcs campaign folder: mean "
        "uncertainty against fleet size, the mean-uncertainty series over mission time "
        "(the paper's Figure 4), solve times, mu / (F1/F2), and a table per grid cell.",
    )
    parser.add_argument("campaign", type=Path, metavar="DIR", help="a gcs campaign --out folder")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="FILE",
        help="the page to write (default DIR/report.html); the PNGs go beside it",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return parser


def run(argv: list[str]) -> int:
    """Parse ``argv`` (after ``gcs campaign report``), write the report, print its path."""
    args = _parser().parse_args(argv)
    from groundstation.runners.campaign.report import CampaignReportError, write_campaign_report

    def say(text: str) -> None:
        if not args.quiet:
            print(f"{_PROG}: {text}", file=sys.stderr, flush=True)

    try:
        page = write_campaign_report(args.campaign, args.out, say=say)
    except CampaignReportError as exc:
        print(f"{_PROG}: error: {exc}", file=sys.stderr)
        return 2
    print(page)
    return 0
