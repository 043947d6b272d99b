"""Measured impact data: the dataset format, its reader and validator, the impact detection and
the jump extraction. Beside the ground; importing it never imports MuJoCo."""
