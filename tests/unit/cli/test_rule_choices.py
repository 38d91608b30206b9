"""The rules a person can choose are the rules the tuning layer has.

``--rule`` (``RuleChoice``) and the site file's ``[online] rule`` are written out by hand (the
command line's help must not import numpy, which the rules' module does), so a rule added to
``TUNING_RULES`` alone would be refused by both: these tests name the list to update.
"""

from __future__ import annotations

import typing

from fuelid.cli._common import RuleChoice
from fuelid.online import Online
from fuelid.tuning import TUNING_RULES


def test_the_command_line_offers_every_rule_and_no_other() -> None:
    assert sorted(choice.value for choice in RuleChoice) == sorted(TUNING_RULES)


def test_the_site_file_accepts_every_rule_and_no_other() -> None:
    accepted = typing.get_args(Online.model_fields["rule"].annotation)
    assert sorted(accepted) == sorted(TUNING_RULES)
