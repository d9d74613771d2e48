"""mavreg's benchmarks: ``python -m benchmarks`` runs the suite (see ``benchmarks/__main__.py``);
each section also runs alone, ``python -m benchmarks.<section> [--quick]``."""
