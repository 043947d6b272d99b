"""Feasibility maps: the highest feasible contact speed over a grid of contact points and settings."""
