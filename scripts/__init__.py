"""The project's scripts, by kind: ``bench`` (measurements), ``build`` (assets and the extension), ``figures``
(pictures and the headless renderer). Run them from the repository root as modules, e.g.
``python -m scripts.bench.bench_fit``; see scripts/README.md."""
