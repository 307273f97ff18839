# Sourced by the experiment scripts that need the library as it was at commit 0e51b82, the last with
# snapshots (snapshot_steps, branch_step), the termination curriculum and the flat schedule settings, all
# removed on 2026-11-26. Sets OLD to a git worktree of that commit in a temporary folder (added once);
# a script then puts "$OLD" first on PYTHONPATH for the commands that need it (the installed packages
# are the same; nothing new is installed).
OLD="${TMPDIR:-/tmp}/mocap-hierarchy-0e51b82"
if [ ! -e "$OLD/.git" ]; then
    git worktree prune
    git worktree add --detach "$OLD" 0e51b82
fi
