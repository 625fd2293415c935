#!/usr/bin/env python3
"""What the README and docs/ promise of the `sls` tool exists: every `sls COMMAND ... --flag`
they show (inline code and fenced blocks) names a command of `sls --help` and flags its
`--help` (or the global `sls --help`) lists. Usage: test_docs_flags.py PATH_TO_SLS REPO_ROOT
(stdlib only)."""
import pathlib
import re
import subprocess
import sys
import unittest

SLS = None
ROOT = None
# Commands the docs name as future work, not as present ones (none now).
FUTURE = set()


def help_text(*command):
    return subprocess.run([SLS, *command, "--help"], capture_output=True, text=True, timeout=60).stdout


def documented_uses(text):
    """(command, flags) for each `sls COMMAND ...` in inline code or a fenced block's line."""
    uses = []
    spans = []
    prose = []
    in_block = False
    for line in text.splitlines():
        if line.strip().startswith("```"):
            in_block = not in_block
            continue
        (spans if in_block else prose).append(line)
    # Inline code may wrap onto the next line.
    spans += [span.replace("\n", " ") for span in re.findall(r"`([^`]+)`", "\n".join(prose))]
    for span in spans:
        for match in re.finditer(r"(?:^|[\s/\"])sls\s+((?:-[-a-z]+\s+)*)([a-z]+)([^;|&]*)", span):
            uses.append((match.group(2), re.findall(r"(--[a-z0-9][a-z0-9-]*)", match.group(1) + match.group(3))))
    return uses


class DocsFlags(unittest.TestCase):
    def test_every_documented_command_and_flag_exists(self):
        global_help = help_text()
        helps = {}
        checked = 0
        files = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
        for path in files:
            for command, flags in documented_uses(path.read_text()):
                if command in FUTURE:
                    continue
                if command not in helps:
                    helps[command] = help_text(command)
                self.assertIn("Usage", helps[command], f"{path.name}: `sls {command}` is not a command")
                for flag in flags:
                    checked += 1
                    self.assertTrue(flag in helps[command] or flag in global_help,
                                    f"{path.name}: `sls {command} {flag}`: not in `sls {command} --help`")
        self.assertGreater(checked, 20)


if __name__ == "__main__":
    SLS, ROOT = sys.argv[1], pathlib.Path(sys.argv[2])
    unittest.main(argv=sys.argv[:1])
