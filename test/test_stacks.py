"""`kill -USR1 <pid>` prints where a bev_mdo process waits (bev_mdo/stacks.py), and it goes on."""
import signal
import subprocess
import sys

from bev_mdo.testing import REPO


def test_sigusr1_prints_every_threads_stack_and_the_process_goes_on():
    code = "\n".join([
        "import sys, threading",
        "from bev_mdo.stacks import dump_stacks_on_sigusr1",
        "dump_stacks_on_sigusr1()",
        "ev = threading.Event()",
        "def waiting_here():",
        "    ev.wait(30)",
        "threading.Thread(target=waiting_here).start()",
        "print('ready', flush=True)",
        "sys.stdin.readline()",
        "ev.set()",
        "print('done')"])
    p = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "ready"
    p.send_signal(signal.SIGUSR1)
    # the dump is written synchronously by the signal handler; then the process is told to finish
    out, err = p.communicate("go\n", timeout=30)
    assert p.returncode == 0 and out.strip() == "done"
    assert "waiting_here" in err and "Thread" in err
