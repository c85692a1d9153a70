"""The ``amorgs`` command line: a dispatcher.

``amorgs step --job <JSON>`` runs one workflow job (each Snakemake rule calls it; the steps, their
settings and outputs are :mod:`amorgs.steps`); the other subcommands are the tools of :mod:`amorgs.tools`.
A user error (bad config, missing or corrupt input) prints one line naming the file or key, no traceback;
so does Ctrl-C (exit status 130).
"""

from __future__ import annotations

import argparse
import sys

from amorgs.errors import ConfigError, InputError
from amorgs.tools import EXAMPLES, add_tools


def cmd_step(args: argparse.Namespace) -> None:
    from amorgs.steps import run_job

    run_job(args.job)


def build_parser() -> argparse.ArgumentParser:
    from amorgs.steps import registry

    parser = argparse.ArgumentParser(prog="amorgs", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    steps = registry()
    p = sub.add_parser(
        "step", help="run one workflow job (what each Snakemake rule calls): its rule, wildcards, files and settings in --job",
        description="Run one job of a workflow step.  Steps:\n" + "\n".join(
            f"  {name:<26} {step.description}" for name, step in steps.items()),
        epilog="example: (Snakemake writes the JSON; `snakemake -n -p TARGET` prints each job's command)\n"
               "  amorgs step --job '{\"rule\": \"fig02_foxholes\", \"wildcards\": {}, \"input\": {}, "
               "\"output\": {\"figure\": \"fig02.png\"}, \"threads\": 1, \"settings\": {}}'",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--job", required=True,
                   help="JSON of the job: rule, wildcards, named input/output, threads, settings (amorgs.steps.job_spec)")
    p.set_defaults(func=cmd_step)
    add_tools(sub)
    for name, tool in sub.choices.items():
        if not tool.epilog and name in EXAMPLES:
            tool.formatter_class = argparse.RawDescriptionHelpFormatter
            tool.epilog = "example:\n  " + EXAMPLES[name]
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (ConfigError, InputError) as exc:
        sys.exit(f"amorgs {args.command}: {exc}")
    except KeyboardInterrupt:  # Ctrl-C: one line, the usual exit status of a command stopped by SIGINT
        print(f"amorgs {args.command}: interrupted", file=sys.stderr)
        sys.exit(130)
