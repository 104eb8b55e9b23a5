model PositionSensor "Measurement of slider B: a first-order low-pass on position and velocity, the position optionally quantised like an encoder's count"
  // No direct feedthrough: the outputs are read off the filter states, never off the inputs.
  // The quantiser is noEvent: it only rounds what the output reports (it does not act on the
  // filter), so it needs no events; resolution = 0 (the default) reports the state itself.
  parameter Real T_f(unit = "s") = 2e-4 "Time constant of the measurement filters (> 0)";
  parameter Real resolution(unit = "m") = 0.0 "Position resolution of the encoder; 0 = no quantisation";
  parameter Real x0(unit = "m") = 0.2329 "Initial filter position (the stroke's start)";
  parameter Real v0(unit = "m/s") = 0.0 "Initial filter velocity";
  input Real x(unit = "m") "Position of slider B (the plant's x_B)";
  input Real v(unit = "m/s") "Velocity of slider B (the plant's v_B)";
  Real x_f(unit = "m", start = x0, fixed = true) "Filtered position (filter state)";
  Real v_f(unit = "m/s", start = v0, fixed = true) "Filtered velocity (filter state)";
  output Real x_m(unit = "m") "Measured position: x_f, rounded to a multiple of resolution when resolution > 0";
  output Real v_m(unit = "m/s") "Measured velocity: v_f";
equation
  T_f * der(x_f) = x - x_f;
  T_f * der(v_f) = v - v_f;
  x_m = if resolution > 0 then resolution * noEvent(floor(x_f / resolution + 0.5)) else x_f;
  v_m = v_f;
end PositionSensor;
