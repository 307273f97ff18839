# Sourced by experiments/student_noise.sh, which needs the library as it was at commit fe34e6b, the only one with
# the online setting student_noise (measured not to help on 2026-11-27, then removed). Sets OLD_NOISE to a git
# worktree of that commit in a temporary folder (added once); the script puts "$OLD_NOISE" first on PYTHONPATH
# for the commands that need it (the installed packages are the same; nothing new is installed).
OLD_NOISE="${TMPDIR:-/tmp}/mocap-hierarchy-fe34e6b"
if [ ! -e "$OLD_NOISE/.git" ]; then
    git worktree prune
    git worktree add --detach "$OLD_NOISE" fe34e6b
fi
