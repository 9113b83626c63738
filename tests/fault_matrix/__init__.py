"""The fault matrix of issue 10: hostile inputs given to the ``bench`` command."""
