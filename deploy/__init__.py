"""Composition: the ``ato`` command, process launchers, the demo and the benchmarks.

The only package that may import both ``onboard`` and ``trackside``.
"""

from deploy._exceptions import DeployError

__all__ = ["DeployError"]
