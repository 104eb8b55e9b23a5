within ToggleLSM;
model PlantNoGravity "The plant with gravity switched off (a horizontal mechanism): a second plant with the same interface contract"
  extends Plant(mechanism(g = 0.0));
end PlantNoGravity;
