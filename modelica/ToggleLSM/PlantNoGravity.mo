within ToggleLSM;
model PlantNoGravity "The plant with gravity switched off (a horizontal mechanism): a second plant with the same interface contract"
  extends Plant(mechanism(g = 0.0));
  annotation(experiment(StartTime = 0, StopTime = 1.5, Tolerance = 1e-8, Interval = 5e-4));
end PlantNoGravity;
