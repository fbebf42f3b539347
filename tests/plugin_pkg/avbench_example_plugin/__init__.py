"""Example avbench plugin: an estimator and two noise terms, registered through entry points."""
