"""s2cl's benchmark suite: what accuracy costs in time, throughput and scaling, and s2cl beside the
tools a user would otherwise use. Run ``python -m bench [--quick] [--only NAME]``; see docs/bench.md."""
