"""The REST API: one router per resource (``routes/``), request and response models
(``schemas``), problem+json errors (``errors``), middleware and dependencies. Routes stay thin:
the work is in ``app.services``."""
