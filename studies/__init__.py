"""Monte Carlo studies: TOML configs (this folder), the runner, tables, figures and the CLI."""

from studies.config import ConfigError, StudyConfig, load_config, parse_config
from studies.runner import run_study

__all__ = ["ConfigError", "StudyConfig", "load_config", "parse_config", "run_study"]
