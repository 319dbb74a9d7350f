"""``ceco benchmark``: named test cases, fixed KPIs, a baseline family and savings at matched comfort.

Modules: :mod:`.front` (the baseline front and matched comfort), :mod:`.schema`
(results format ``ceco-benchmark/2`` and its validator), :mod:`.cases` (test-case
files). Method and formats: docs/benchmark.md.
"""
