"""``python -m deploy`` is ``ato``."""

from deploy.cli import app

app()
