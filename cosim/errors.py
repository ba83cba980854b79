"""Errors a user can cause. The CLI turns each into one line on stderr and exit code 2."""


class CosimError(Exception):
    """A problem with the user's input (file, config, map, parameter): message names it and the fix."""


class ConfigError(CosimError):
    """A config value is missing, unknown, of the wrong type or impossible. The message starts with the key path."""

    def __init__(self, path: str, problem: str):
        self.path = path
        self.problem = problem
        super().__init__(f"config {path}: {problem}" if path else f"config: {problem}")
