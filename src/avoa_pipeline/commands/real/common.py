"""What every real-data command shares: the config (the group's ``--config``) and no lock (each
writes through ``jobs.real``'s atomic writers, as the workflow's rules do)."""

from __future__ import annotations


def no_lock(args) -> None:
    return None


def config(args) -> dict:
    from ... import config as config_mod

    return config_mod.load(args.config)
