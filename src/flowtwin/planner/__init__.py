"""Motion planners: trapezoidal look-ahead as Klipper and Marlin execute it."""
