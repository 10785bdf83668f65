"""Execute one notebook with papermill, its kernel reached over sockets of its own.

    python -m avoa_pipeline.notebook NOTEBOOK EXECUTED -k KERNEL [-p NAME VALUE ...]

What ``papermill NOTEBOOK EXECUTED -k KERNEL -p NAME VALUE ...`` does (the same engine, the same
parameter cell; each VALUE read as papermill's command line reads it: True, False, None, an
integer, a float, else the text), with one difference, and the reason this module exists: the
kernel listens on local (IPC) sockets in a folder made for it, not on TCP ports.

Why: jupyter_client picks a kernel's five TCP ports by binding to port 0 and closing the socket
again; the kernel binds them later. Two notebooks started at once by different processes (the
workflow at ``-j2``, the test suite's workers) can be handed the same free port in between, and
the later kernel then dies before it answers ("Kernel died before replying to kernel_info":
six errors of one CI run, ``tests/workflow/test_tiny.py``). Sockets that are files in a folder
no other kernel knows cannot meet. papermill's command line has no way to choose the transport
(jupyter_client's ``transport`` setting is read from a configuration papermill never loads), so
the kernel manager is given here, through papermill's Python call.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile

from jupyter_client.manager import AsyncKernelManager


class PrivateSocketKernelManager(AsyncKernelManager):
    """nbclient's kernel manager (asynchronous, as its default) on IPC sockets in a temporary
    folder of its own, removed when the kernel's files are cleaned up."""

    def _transport_default(self) -> str:  # traitlets' dynamic default of ``transport``
        return "ipc"

    def _ip_default(self) -> str:  # with IPC, the sockets' path prefix
        self._socket_dir = tempfile.mkdtemp(prefix="avoa-kernel-")
        return os.path.join(self._socket_dir, "k")

    def cleanup_ipc_files(self) -> None:
        super().cleanup_ipc_files()
        folder = getattr(self, "_socket_dir", None)
        if folder:
            shutil.rmtree(folder, ignore_errors=True)


def value(text: str):
    """A ``-p`` value as papermill's command line reads it."""
    special = {"True": True, "False": False, "None": None}
    if text in special:
        return special[text]
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m avoa_pipeline.notebook", description=__doc__)
    ap.add_argument("notebook")
    ap.add_argument("executed")
    ap.add_argument("-k", "--kernel", required=True)
    ap.add_argument("-p", "--parameter", nargs=2, action="append", default=[],
                    metavar=("NAME", "VALUE"))  # fmt: skip
    args = ap.parse_args(argv)
    import papermill

    papermill.execute_notebook(
        args.notebook, args.executed, parameters={k: value(v) for k, v in args.parameter},
        kernel_name=args.kernel, progress_bar=False,
        kernel_manager_class=PrivateSocketKernelManager,
    )  # fmt: skip


if __name__ == "__main__":
    main()
