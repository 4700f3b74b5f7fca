"""The remote operator's hands in lockstep tests: the scenario runner's simulated operator."""

from deploy.scenario.operator import ANSWERED, LockstepOperator

__all__ = ["ANSWERED", "LockstepOperator"]
