package ExchangeModels "Small models for the Model Exchange versus Co-Simulation checks (tests/test_model_exchange.py)"
  model BouncingBall "A ball dropped from rest at height h0 onto the floor, restitution e"
    parameter Real g(unit = "m/s2") = 9.81 "Gravity";
    parameter Real e = 0.8 "Coefficient of restitution";
    parameter Real h0(unit = "m") = 1.0 "Initial height";
    Real h(unit = "m", start = h0, fixed = true) "Height above the floor";
    Real v(unit = "m/s", start = 0.0, fixed = true) "Velocity, upwards";
  equation
    der(h) = v;
    der(v) = -g;
    when h < 0 then
      reinit(v, -e * pre(v));
    end when;
    annotation(experiment(StartTime = 0, StopTime = 2.0, Interval = 0.001));
  end BouncingBall;

  model VanDerPol "Van der Pol oscillator x'' - mu (1 - x^2) x' + x = 0"
    parameter Real mu = 1.0 "Damping parameter";
    Real x(start = 2.0, fixed = true) "Position";
    Real y(start = 0.0, fixed = true) "Velocity";
  equation
    der(x) = y;
    der(y) = mu * (1 - x ^ 2) * y - x;
    annotation(experiment(StartTime = 0, StopTime = 10, Interval = 0.01));
  end VanDerPol;
end ExchangeModels;
