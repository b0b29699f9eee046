"""Imported first by the local runner's fork server: it dies with the server (``_lifeline``).

If the server died before this line ran, the fork server still exits by itself: its pipe from
the server breaks (multiprocessing's own check).
"""

import os

from app.jobs._lifeline import die_with_parent

die_with_parent(os.getppid())
