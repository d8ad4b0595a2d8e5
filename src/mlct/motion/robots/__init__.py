"""Robot targets: a generated motion retargeted to a humanoid robot's joint angles.

g1.py holds the Unitree G1's kinematic table, chain.py the forward kinematics and the damped
least-squares solver, retarget.py the retarget and files.py the CSV / .npz writers
(docs/export.md, "Robots: Unitree G1").
"""
