"""BioPlan: bio-inspired trajectory planning from human EMG and pose recordings."""

from app.logs import set_log_level  # ``app.set_log_level("INFO")``, as MNE's

__version__ = "0.1.0"

__all__ = ["__version__", "set_log_level"]
