"""`sls`'s global options (--json, -q, -v) after the command as well as before it, for every
command `sls --help` lists: each command run so that it parses and then fails in its work (or,
for info, devices and a two-frame bench, succeeds) prints JSON on stdout either way, with the same exit status.
Usage: test_sls_global_options.py SLS"""
import json
import os
import re
import subprocess
import sys
import tempfile
import unittest

SLS = None


def run(*args):
    return subprocess.run([SLS, *args], capture_output=True, text=True, timeout=120)


class GlobalOptionsAfterTheCommand(unittest.TestCase):
    def test_every_command_takes_json_quiet_and_verbose_before_and_after_it(self):
        with tempfile.TemporaryDirectory() as tmp:
            regular_file = os.path.join(tmp, "a-file")
            open(regular_file, "w").close()
            missing = os.path.join(tmp, "missing")
            # One invocation per command that parses, and then does its work or fails in it.
            invocations = {
                "info": [],
                "devices": [],
                "bench": ["--preset", "ci", "--frames", "2"],
                "inspect": [missing],
                "eval": ["--result", missing, "--truth", missing],
                "decode": ["--input", missing, "--out", os.path.join(tmp, "decoded")],
                "scan": ["--input", missing, "--out", os.path.join(tmp, "scanned")],
                "sim": ["--preset", "ci", "--frames", "1", "--out", regular_file],
                "calibrate": ["--input", missing, "--out", os.path.join(tmp, "calibration.yml")],
                "import": ["--images", missing, "--patterns", missing, "--calibration", missing,
                           "--out", os.path.join(tmp, "imported")],
            }
            listed = re.findall(r"^  (\w+)\s", run("--help").stdout.split("Subcommands:")[-1], re.MULTILINE)
            self.assertGreater(len(listed), 5, "could not read the commands from sls --help")
            self.assertEqual(sorted(listed), sorted(invocations), "a command without an invocation here")
            for command, args in invocations.items():
                with self.subTest(command=command):
                    before = run("--json", "-q", "-v", command, *args)
                    after = run(command, *args, "--json", "-q", "-v")
                    self.assertNotEqual(after.returncode, 2, after.stderr)
                    self.assertEqual(after.returncode, before.returncode, after.stderr)
                    self.assertEqual(json.loads(after.stdout).keys(), json.loads(before.stdout).keys())

    def test_an_unknown_option_after_the_command_is_still_a_usage_error(self):
        result = run("info", "--no-such-option")
        self.assertEqual(result.returncode, 2)
        self.assertIn("--no-such-option", result.stderr)


if __name__ == "__main__":
    SLS = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
