model GuidedMass "TEMPLATE plant to copy: slider B as a mass on a guide, driven by a thrust constant times iq_ref"
  // Only what the plant contract requires (src/toggle_cosim/plant/contract.yaml); x_B0 is an
  // optional parameter the run sets to the scenario's stroke.x_start.
  parameter Real m_B(unit = "kg") = 4.43 "Mass of slider B (contract parameter)";
  parameter Real mu = 0.2 "Coefficient of dry friction on the guide (contract parameter)";
  parameter Real x_B0(unit = "m") = 0.2329 "Initial position of slider B (optional contract parameter)";
  parameter Real K_F(unit = "N/A") = 56.96 "Thrust constant of the drive";
  parameter Real v_eps(unit = "m/s") = 0.01 "Velocity scale of the regularised Coulomb friction";
  parameter Real g(unit = "m/s2") = 9.81 "Gravitational acceleration";
  input Real iq_ref(unit = "A") "Current command i_q* (contract input)";
  input Real F_E(unit = "N") "External force on slider B, >= 0 resists the forward stroke (contract input)";
  output Real x_B(unit = "m", start = x_B0, fixed = true) "Position of slider B (contract output)";
  output Real v_B(unit = "m/s", start = 0.0, fixed = true) "Velocity of slider B (contract output)";
equation
  der(x_B) = v_B;
  m_B * der(v_B) = K_F * iq_ref - F_E - mu * m_B * g * tanh(v_B / v_eps);
end GuidedMass;
