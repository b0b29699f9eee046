"""Where jobs run: ``JobRunner`` (``LocalRunner``: a process per job; ``DaskRunner``: a Dask
cluster) and the job functions of ``tasks`` (plain data in, plain data out). No database: the
service layer (``app.services``) records what the runners report."""

from app.jobs.runner import DaskRunner, JobEvent, JobRunner, LocalRunner, make_runner

__all__ = ["DaskRunner", "JobEvent", "JobRunner", "LocalRunner", "make_runner"]
