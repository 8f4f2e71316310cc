"""Runs every ```bash block of README.md as a user would, so the README cannot drift from the code.

Each block runs in the order of the README, as one ``bash -eu -o pipefail`` script, in one scratch
directory shared by all blocks (a later block may use what an earlier one wrote, e.g. the bags of
``synth-bag``) that links the repository's ``.venv`` and ``config``. The line just before a block's
fence may set how it runs:

* (nothing): every command must exit 0.
* ``<!-- readme-test: nodes -->``: each line starts a node that must say it is ready, keep running, and
  stop with exit code 0 and no traceback on Ctrl-C.
* ``<!-- readme-test: tested by test/FILE.py -->``: that test runs the block with its expected
  output; this one only checks that the file exists and reads the README.
* ``<!-- readme-test: skip: REASON -->``: not runnable here (a display, a ROS install); the reason is
  shown as the skip reason.

Synopses with placeholders (``[--option N]``, ``BAG...``) are ```text blocks, never run. Links within the
README must name one of its headings, and its contents list must name every section.

Blocks that start ROS nodes (the ``nodes`` policy, a node-graph ``game`` or ``strategy-test``) are marked
``integration`` and so run in `make test`'s second part, alone; the others run in its first part, all on
one pytest-xdist process in README order (``--dist loadfile`` keeps a file's tests together), so their
shared scratch directory holds what the blocks before them wrote. No node block reads a file another
block wrote.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from air_hockey_agent.nodes.runtime import READY_MARKER

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
BLOCK_TIMEOUT = 600.0  # [s] per block; the longest (sysid, a game) take about a minute here
NODE_READY_TIMEOUT = 60.0  # [s]
NODE_STOP_TIMEOUT = 20.0  # [s]
SETUP = ("make game", "make test")  # the README's two set-up commands: CI runs them itself
POLICY = re.compile(r"<!--\s*readme-test:\s*(.*?)\s*-->")
NODE_GRAPH = re.compile(r"air-hockey (game|strategy-test)(?=\s|$)(?!.*--in-process)")  # starts nodes


@dataclass(frozen=True)
class Block:
    line: int     # of the opening fence
    policy: str   # "run", "nodes", "tested by ...", "skip: ..."
    text: str


def bash_blocks(text: str) -> list[Block]:
    """The README's ```bash blocks with the policy set on the line before each."""
    lines, blocks, i = text.splitlines(), [], 0
    while i < len(lines):
        if lines[i].strip() == "```bash":
            end = next(j for j in range(i + 1, len(lines)) if lines[j].strip() == "```")
            match = POLICY.fullmatch(lines[i - 1].strip()) if i > 0 else None
            blocks.append(Block(i + 1, match.group(1) if match else "run", "\n".join(lines[i + 1:end]) + "\n"))
            i = end
        i += 1
    return blocks


def commands(block: Block) -> list[str]:
    return [line.split("  #")[0].strip() for line in block.text.splitlines() if line.strip()]


def starts_nodes(block: Block) -> bool:
    """Whether running ``block`` starts ROS nodes (a node per line, or a node-graph game)."""
    return block.policy == "nodes" or (block.policy == "run" and any(map(NODE_GRAPH.search, commands(block))))


def as_param(block: Block):
    """``block`` as a test parameter marked for the part of `make test` it runs in (module docstring)."""
    return pytest.param(block, marks=[pytest.mark.integration] if starts_nodes(block) else [],
                        id=f"line{block.line}")


BLOCKS = bash_blocks(README.read_text())


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    work = tmp_path_factory.mktemp("readme")
    for name in (".venv", "config"):
        (work / name).symlink_to(ROOT / name)
    return work


def test_every_block_has_a_known_policy_and_no_placeholders():
    assert BLOCKS, "README.md has no ```bash block"
    for block in BLOCKS:
        assert block.policy in ("run", "nodes") or block.policy.startswith(("tested by test/", "skip: ")), \
            f"README.md line {block.line}: unknown readme-test policy '{block.policy}'"
        if block.policy.startswith("skip: "):
            continue
        for command in commands(block):
            assert not re.search(r"\[--|\.\.\.|<[a-z ]+>", command), \
                f"README.md line {block.line}: '{command}' has a placeholder (synopses go in ```text blocks)"


@pytest.fixture
def block_env(tmp_path) -> dict:
    """The blocks' environment: our Fast DDS profile, the private domain, a temporary ROS_HOME (conftest's
    ``ros_env``, not requested by name: that would put every block in `make test`'s ROS part)."""
    from air_hockey_agent.tools.ros_env import ros_environment
    return ros_environment(domain_id=int(os.environ["ROS_DOMAIN_ID"]), ros_home=tmp_path / "ros_home")


@pytest.mark.parametrize("block", [as_param(b) for b in BLOCKS])
def test_readme_block(block: Block, scratch: Path, block_env):
    if all(c.startswith(SETUP) for c in commands(block)):
        pytest.skip("the README's set-up commands: CI runs `make test` itself, and `make game` is tested by "
                    "test/test_node_cli.py")
    if block.policy.startswith("skip: "):
        pytest.skip(block.policy[len("skip: "):])
    if block.policy.startswith("tested by "):
        test_file = ROOT / block.policy[len("tested by "):]
        assert test_file.exists() and "README" in test_file.read_text(), \
            f"README.md line {block.line}: {test_file} does not exist or does not read the README"
        return
    if block.policy == "nodes":
        for command in commands(block):
            run_node(command, scratch, block_env, block.line)
        return
    result = subprocess.run(["bash", "-eu", "-o", "pipefail", "-c", block.text], cwd=scratch, env=block_env,
                            capture_output=True, text=True, timeout=BLOCK_TIMEOUT)
    assert result.returncode == 0, (f"README.md block at line {block.line} exited {result.returncode}:\n"
                                    f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}")
    assert "Traceback" not in result.stderr, result.stderr[-3000:]


def run_node(command: str, cwd: Path, env: dict, line: int) -> None:
    """Start ``command``, wait for the ready line, interrupt it like Ctrl-C, expect a clean exit."""
    proc = subprocess.Popen(["bash", "-c", f"exec {command}"], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    output: list[str] = []
    reader = threading.Thread(target=lambda: output.extend(proc.stdout), daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + NODE_READY_TIMEOUT
        while time.monotonic() < deadline and proc.poll() is None and READY_MARKER not in "".join(output):
            time.sleep(0.1)
        assert proc.poll() is None, f"README.md line {line}: '{command}' exited {proc.returncode}:\n{''.join(output)}"
        assert READY_MARKER in "".join(output), f"README.md line {line}: '{command}' never said it was ready"
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=NODE_STOP_TIMEOUT)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        reader.join(timeout=5.0)
    text = "".join(output)
    assert proc.returncode == 0, f"README.md line {line}: '{command}' exited {proc.returncode} on Ctrl-C:\n{text}"
    assert "Traceback" not in text, text


def test_blocks_are_found_with_their_policies():
    text = ("intro\n```bash\necho one\n```\n<!-- readme-test: skip: needs a display -->\n```bash\nviewer\n```\n"
            "```text\ntool [--flag N]\n```\n<!-- readme-test: nodes -->\n```bash\nnode --ros-args\n```\n")
    blocks = bash_blocks(text)
    assert [(b.line, b.policy, b.text) for b in blocks] == [
        (2, "run", "echo one\n"), (6, "skip: needs a display", "viewer\n"), (13, "nodes", "node --ros-args\n")]


def test_blocks_that_start_nodes_are_told_apart():
    def block(policy: str, text: str) -> Block:
        return Block(1, policy, text)
    assert starts_nodes(block("nodes", "visualizer --ros-args\n"))
    assert starts_nodes(block("run", ".venv/bin/air-hockey game --goals 1 --duration 10 --json\n"))
    assert starts_nodes(block("run", "air-hockey synth-bag shots\nair-hockey strategy-test --trials 1\n"))
    assert not starts_nodes(block("run", ".venv/bin/air-hockey game --in-process --duration 6 --seed 3\n"))
    assert not starts_nodes(block("run", "air-hockey strategy-test --in-process --trials 1  # no nodes\n"))
    assert not starts_nodes(block("run", "air-hockey game-check seed3\nair-hockey eval-prediction shots\n"))
    assert not starts_nodes(block("tested by test/test_node_cli.py", "air-hockey game --duration 30\n"))
    assert [b.line for b in BLOCKS if starts_nodes(b)], "README.md: no block starts nodes (the split is untested)"


def heading_anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation but hyphens dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_every_link_within_the_readme_names_a_heading_and_the_contents_list_every_section():
    text = README.read_text()
    headings = re.findall(r"^#{2,3} (.+)$", text, re.M)
    anchors = {heading_anchor(h) for h in headings}
    broken = sorted(set(re.findall(r"\]\(#([^)]+)\)", text)) - anchors)
    assert not broken, f"README.md: links to no heading: {broken}"
    contents = text[text.index("Contents:"):text.index("## ")]
    missing = [h for h in headings if f"(#{heading_anchor(h)})" not in contents]
    assert not missing, f"README.md: sections missing from the contents: {missing}"


def test_heading_anchors_follow_githubs_rule():
    assert heading_anchor("Issue #13's targets, command by command") == "issue-13s-targets-command-by-command"
    assert heading_anchor("Installation notes (the decisions behind `scripts/setup_venv.sh`)") == \
        "installation-notes-the-decisions-behind-scriptssetup_venvsh"
