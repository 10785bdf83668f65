"""The commands of ``python -m avoa_pipeline``, one module each, keyed by name in ``REGISTRY``
(as ``optimizers/`` registers algorithms). Importing this package registers them all; a new
command is a module here and its name in :data:`COMMANDS`."""

from importlib import import_module

from .registry import REGISTRY, Command, add_commands, register

COMMANDS = ("fit", "generate", "recovery", "convert", "diagnose", "simulate", "export",
            "estimate", "real")  # fmt: skip
"""The command modules, imported (so registered) in the order ``--help`` lists them."""

for _module in COMMANDS:
    import_module(f".{_module}", __name__)

__all__ = ["COMMANDS", "REGISTRY", "Command", "add_commands", "register"]
