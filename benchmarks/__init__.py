"""Benchmark commands: ``python -m benchmarks.<name> [--quick]`` (see benchmarks/README.md)."""
