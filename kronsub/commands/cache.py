"""``kronsub cache info|clear``: kronsub's caches (derived known systems, compiled models)."""
from __future__ import annotations

import click

from .common import run_command, say


@click.group()
def cache():
    """Show or clear kronsub's caches (derived known systems, compiled models)."""


def _size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return ""


@cache.command("info")
def cache_info():
    """Where the cache is, how many entries it holds and their sizes."""
    from .. import cache as store

    def job():
        found = store.info()
        if found.folder is None:
            say(f"cache: off ({store.CACHE_ENV}=off)", err=False)
            return
        exists = found.folder.exists()
        reason = store.unsafe_reason(found.folder) if exists else store.missing_reason(found.folder)
        say(f"cache: {found.folder}" + (f" (not used: {reason})" if reason else "")
            + ("" if exists or reason else " (empty)"), err=False)
        say(f"derived known systems: {found.systems} ({_size(found.systems_bytes)})", err=False)
        say(f"compiled models: {found.libraries} ({_size(found.libraries_bytes)})", err=False)
        say(f"kept outputs: {found.kept} ({_size(found.kept_bytes)})", err=False)

    run_command(job)


@cache.command("clear")
def cache_clear():
    """Remove kronsub's own entries from the cache (nothing else in the folder)."""
    from .. import cache as store

    def job():
        removed = store.clear()
        if removed.folder is None:
            say(f"cache: off ({store.CACHE_ENV}=off)", err=False)
            return
        say(f"removed from {removed.folder}: derived known systems: {removed.systems} "
            f"({_size(removed.systems_bytes)}), compiled models: {removed.libraries} "
            f"({_size(removed.libraries_bytes)}), kept outputs: {removed.kept} ({_size(removed.kept_bytes)})",
            err=False)

    run_command(job)


__all__ = ["cache", "cache_clear", "cache_info"]
