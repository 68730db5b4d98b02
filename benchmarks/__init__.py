"""Benchmarks of flowtwin (``make bench``): figures and ratios against named peers."""
