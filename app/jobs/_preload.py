"""Imported once by the local runner's fork server so that forked job processes start warm."""

from app.jobs.tasks import preload

preload()
