"""The documents' examples, run as written (tests/docs/test_examples.py)."""
