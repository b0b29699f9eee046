"""BioPlan: bio-inspired trajectory planning from human EMG and pose recordings."""

__version__ = "0.1.0"
