"""The lab: the tools that drive the renderer headless and measure it.

The CLI, the benchmark, the papers' experiments, the speed/accuracy study, the photon-mapping
tables, the reports, the CPU photon reference and the full-quality reference path. The lab sits
above ``render`` and the models and below nothing but ``ui`` (whose launcher calls the CLI); the
import contracts in ``pyproject.toml`` keep it so.
"""
