"""Stage 5, runs: a scenario as a learning problem, executors, the resumable run store,
robustness evaluation, and the optimise-verify-report workflow."""
