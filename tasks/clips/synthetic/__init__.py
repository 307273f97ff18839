"""The built-in synthetic clip library: motions authored in task space, solved by IK."""
