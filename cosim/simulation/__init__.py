"""One run: the loop, its configuration and its metrics."""
