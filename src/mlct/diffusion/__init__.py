"""Diffusion process of the latent consistency model: schedule, parameterization, solver."""
