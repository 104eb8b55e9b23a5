model VanDerPol "The Van der Pol oscillator: a model toggle-cosim does not ship, for the FMI-LS-REF tests"
  parameter Real mu = 1.0 "Damping";
  Real x0(start = 2.0, fixed = true) "Position";
  Real x1(start = 0.0, fixed = true) "Velocity";
  annotation(experiment(StartTime = 0, StopTime = 5, Interval = 0.01, Tolerance = 1e-8));
equation
  der(x0) = x1;
  der(x1) = mu * (1 - x0 ^ 2) * x1 - x0;
end VanDerPol;
