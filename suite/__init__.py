"""hwyeval suite: catalog, SUMO world, runner, executors, metrics, Rerun logs, CLI."""
