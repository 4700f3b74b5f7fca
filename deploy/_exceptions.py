"""The exception tree of the ``deploy`` package, in one place.

::

    DeployError (Exception)
    ├── ScenarioFileError (ValueError)   a scenario file that cannot be used: where, and why
    │                                    (deploy.scenario.loader)
    ├── SpaceFileError (ValueError)      a generator's space file that cannot be used
    │                                    (deploy.scenario.space)
    ├── ScenarioRunError (RuntimeError)  a run that could not be carried out, not an expectation
    │                                    that failed (deploy.scenario.run_context)
    ├── ScenarioError (ValueError)       a VC catalogue scenario that cannot be run
    │                                    (deploy.bench.vc_scenarios)
    ├── RecordingError (ValueError)      an offline SFA recording unreadable or inconsistent
    │                                    (deploy.bench.sfa_recording)
    ├── LinkProxyError (OSError)         the link proxy could not start or did not answer
    │                                    (deploy.link_proxy)
    └── ChildError (RuntimeError)        a child process not started or not ready
        └── UpError                      a part of ``ato up`` (deploy.up)

Each is defined beside the code that raises it and derives from :class:`DeployError`, so a
caller (the CLI) catches the package's errors in one ``except``; the CLI turns them into a
message and an exit status.
"""

from __future__ import annotations

__all__ = ["DeployError"]


class DeployError(Exception):
    """Base of every error raised by ``deploy``."""
