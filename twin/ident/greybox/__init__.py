"""Grey-box identification of the input gain from GNSS, heading and PWM [Morel-2024]: regressors
by operating region, static and first-order dynamic thruster models (Props. 1-3, eq. 35), least
squares, split tables (Tables 4-9), the physical quantities they imply, and the plain baseline."""
