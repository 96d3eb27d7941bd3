"""Inverse kinematics: which joint values put a chain's end frame at a target pose.

``poekin.ik._angles`` holds what every solver shares: bringing revolute angles into the joint
limits by whole turns.
"""
