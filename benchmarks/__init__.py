"""Benchmarks you can rerun: ``python -m benchmarks.<name>``; the targets and figures are in
docs/benchmarks.md."""
