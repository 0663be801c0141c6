"""Inertial navigation core: Earth model, attitude, strapdown mechanization, error models.

Frames, units and signs: ``docs/conventions.md`` (spec §0): navigation frame ENU,
body frame x right / y forward / z up, Euler ``[pitch, roll, yaw]`` with
``C_b^n = R_z(ψ) R_x(θ) R_y(γ)``, position ``[L, λ, h]`` in rad, rad, m.
"""
