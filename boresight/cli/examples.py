"""Examples shown at the end of every ``boresight COMMAND --help`` (the epilog).

A command that sets its own epilog keeps it; the others get theirs from ``EXAMPLES`` here, so one
file lists how each command is meant to be called. ``tests/cli/test_cli_help.py`` checks that every
command's help ends with examples.
"""

from __future__ import annotations

import argparse

__all__ = ["EXAMPLES", "add_examples"]

EXAMPLES = {
    "simulate": """examples:
  boresight simulate kiev2012-kalman20 --seed 7 --out out          # a shipped scenario, by name
  boresight simulate my-scenario.toml --runs 100 --out out          # a scenario file, by path""",
    "montecarlo": """examples:
  boresight montecarlo kiev2012-sensitivity                         # the seminar's headline study (45 000 runs)
  boresight montecarlo kiev2012-kalman20 --runs 2000 --algorithm all --out out/k20
  boresight montecarlo kiev2012-kalman20 --runs 2000 --weighting gls --algorithm image_plane  # GLS σ
  boresight montecarlo strip.ecsv --runs 200                       # a pushbroom file's σ against a resimulation of it""",
    "sensitivity": """examples:
  boresight sensitivity kiev2012-sensitivity                        # eq 28 table, error budget
  boresight sensitivity kiev2012-sensitivity --runs 5000 --algorithm image_plane --no-plots
  boresight sensitivity strip.ecsv --strip strip2.ecsv              # a pushbroom campaign: pixels against the tracker""",
    "reproduce": """examples:
  boresight reproduce kiev2012 --out docs/                          # regenerate docs/reproduction.md""",
    "diagnose": """examples:
  boresight diagnose flight.ecsv                                    # what is missing from the model?
  boresight diagnose strip.ecsv                                     # a pushbroom file: the line-scanner effects""",
    "plan": """examples:
  boresight plan kiev680                                      # choose passes for a target σθ (writes out/kiev680-plan)
  boresight plan plans/kiev680.toml --mc-check 2000          # and check the chosen campaign by Monte Carlo
  boresight plan stars-fusion                                 # landmark passes and star-frame segments as candidates""",
    "pointing": """examples:
  boresight pointing sea-sky                                        # USV sea-sky perpendicularity on the paper's data""",
    "docs": """examples:
  boresight docs                                                    # the guides shipped with the package
  boresight docs tutorial-flight-data                               # print one (Markdown)""",
}


def add_examples(subparsers_action) -> None:
    """Give every sub-command (and sub-sub-command) without an epilog its examples."""
    for name, p in subparsers_action.choices.items():
        if p.epilog is None and name in EXAMPLES:
            p.epilog = EXAMPLES[name]
            p.formatter_class = argparse.RawDescriptionHelpFormatter
        for action in p._actions:  # nested sub-commands (pointing sea-sky, …) inherit their parent's examples
            if isinstance(action, argparse._SubParsersAction):
                for child in action.choices.values():
                    if child.epilog is None and name in EXAMPLES:
                        child.epilog = EXAMPLES[name]
                        child.formatter_class = argparse.RawDescriptionHelpFormatter
