"""Benchmarks outside the core package: one module per topic with run(quick) -> dict and markdown(results) -> str."""
TOPICS = ("metrics", "app_latency")
