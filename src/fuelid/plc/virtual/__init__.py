"""The virtual PLC: the nonlinear fuel loop with its PLC emulated, on real protocol servers."""
