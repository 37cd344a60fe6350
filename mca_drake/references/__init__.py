"""Vehicle motion: recordings (CSV), JSBSim flights, references y_ref, open-loop excitation."""
