"""Kalman / extended Kalman filtering, gating and RTS smoothing."""
