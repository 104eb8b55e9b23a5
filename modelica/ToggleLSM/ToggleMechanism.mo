within ToggleLSM;
model ToggleMechanism "Toggle mechanism with joint Coulomb friction: the Lagrange-multiplier DAE of eqs. (17)-(18) at acceleration level"
  /* Coordinates q = (theta1, theta2, theta5): lever 2, link 3 (A-B) and link 5 (D-C); one degree
     of freedom, two loop closures
       Phi1 = r1 sin(theta1) + r3 sin(theta2) - f            (slider B on its guide y = f)
       Phi2 = h - r4 sin(theta1 + phi) - r5 sin(theta5)      (slider C on its guide y = h).
     Eq. (18), M qdd + (Phi_q' + Q_f') lambda = Q and Phi_q qdd = gamma, is written body by body
     as virtual work: each generalized equation sums m a_G . dp_G/dq_j + J alpha dtheta/dq_j
     over the bodies, gravity on links 3 and 5, the flange forces on the sliders and the
     constraint and friction columns. The constraints enter at acceleration level
     (Phi'' = Phi_q qdd - gamma) with Baumgarte terms that vanish on the constraint manifold and
     pull numerical drift back to it. Q_f' is eq. (17) exactly as the paper writes it: the
     friction multiplies lambda, not |lambda|.
     Three friction models (parameter frictionModel), on the rows R_i of Q_f' lambda / mu:
       1 paper        tau_i = mu sgn(omega_i) R_i                 (eq. (17), the default)
       2 dissipative  tau_i = mu sgn(omega_i) |R_i|               (friction power >= 0)
       3 stick_slip   as 2 while the mechanism slips; when omega1 would reverse, the
                      mechanism sticks: all velocities are set to zero, and the static friction
                      keeps alpha1 = -stickDecay omega1: joints theta2 and theta5 carry their
                      full static friction in the direction the mechanism would break away
                      (dStick), the lever's joint the rest, so that T_st, the total projected on
                      theta1, is what holds the mechanism. When T_st exceeds the static capacity
                      mu_s sum_i |domega_i/domega1| |R_i| in direction dStick, it slips again in
                      that direction; at that instant the stuck and the slipping equations are
                      the same (with mu = mu_s), so the slip starts with alpha1 >= 0 in its
                      direction and cannot stick again at the same instant.
     Friction at rest (Filippov), in every model: the linkage has one degree of freedom, so all
     joints rest together, and one mode variable for the mechanism (dir = +1 forward, stuck,
     dir = -1 backward) holds it at rest while the holding torque T_st is inside the cone
     |T_st| <= T_s, T_s = mu0 sum_i |k_i| |R_i| (mu0 = mu under models 1 and 2, muStatic under
     model 3). Entering rest: omega1 crosses zero against dir (indicator -dir omega1); leaving:
     dStick T_st - T_s crosses zero. A reversal with T_st outside the cone is a stick and a
     breakaway in one event iteration. Models 1 and 2 start slipping with sgn = 0 (their first
     motion sets dir) and keep the velocities' residuals at the stick (wHold), so a reversal that
     passes through rest leaves the state untouched; model 3 starts stuck and zeroes them.
     The joints' signs follow the one degree of freedom, sgn(omega_i) = sgn(k_i) sgn(omega1): a
     zero crossing of omega_i that contradicts it (the constraint residual while omega1 creeps
     through zero) is held until k_i sgn1 agrees (want2, want5), except near k_i = 0 (jointTurn).
     |R_i| is mu sgn(R_i) R_i with sgn(R_i) a relation latch, so the block stays linear in
     (alpha, lambda); under model 1 the latches are watched only at rest, where the cone needs
     |R_i|. Indicators that only matter in a mode are zero outside it, so a run of model 1 or 2
     that never comes to rest integrates exactly as the plain sign latches integrate it. */
  constant Real pi = 3.141592653589793;
  // Geometry (assumed, see docs/model.md)
  parameter Real r1(unit = "m") = 0.10 "Lever arm O-A (assumed)";
  parameter Real r3(unit = "m") = 0.27 "Length of link A-B (assumed)";
  parameter Real r4(unit = "m") = 0.10 "Lever arm O-D (assumed)";
  parameter Real r5(unit = "m") = 0.27 "Length of link D-C (assumed)";
  parameter Real f(unit = "m") = 0.0 "Height of the guide of slider B (assumed)";
  parameter Real h(unit = "m") = 0.10 "Height of the guide of slider C (assumed)";
  parameter Real phi(unit = "rad") = 2.8972465583105871 "Angle between the lever arms O-A and O-D, 166 deg (assumed)";
  // Inertia (assumed)
  parameter Real m2(unit = "kg") = 0.8 "Mass of the lever, centre of mass at the pivot O (assumed)";
  parameter Real J2(unit = "kg.m2") = 0.003 "Moment of inertia of the lever about O (assumed)";
  parameter Real m3(unit = "kg") = 0.3 "Mass of link A-B, a uniform rod (assumed)";
  parameter Real J3(unit = "kg.m2") = m3 * r3 ^ 2 / 12 "Moment of inertia of link A-B about its centre";
  parameter Real m_B(unit = "kg") = 4.43 "Mass of slider B (nominal)";
  parameter Real m5(unit = "kg") = 0.3 "Mass of link D-C, a uniform rod (assumed)";
  parameter Real J5(unit = "kg.m2") = m5 * r5 ^ 2 / 12 "Moment of inertia of link D-C about its centre";
  parameter Real m_C(unit = "kg") = 1.5 "Mass of slider C, the PMLSM mover (assumed)";
  parameter Real g(unit = "m/s2") = 9.81 "Gravitational acceleration, along -y";
  parameter Real mu = 0.2 "Coefficient of dry friction in the joints, eq. (17); 0: no friction";
  parameter Integer frictionModel = 1 "Joint friction model: 1 paper eq. (17), 2 dissipative, 3 stick_slip";
  parameter Real mu_s = 0.2 "Static coefficient of friction (frictionModel = 3)";
  parameter Real stickDecay(unit = "1/s") = 1000 "Rate at which a stuck mechanism's residual velocity decays (frictionModel = 3)";
  parameter Real stickCompliance = 1e-12 "Residual acceleration of a stuck mechanism per N.m of holding torque, rad/s2 (model 3; numerical regularisation)";
  parameter Real muStatic = if frictionModel == 3 and mu_s > mu then mu_s else mu "Static coefficient in force: mu_s under model 3 where it exceeds mu (breakaway is otherwise continuous), mu under models 1 and 2";
  parameter Real wDiss = if frictionModel == 1 then 0.0 else 1.0 "1 where the sign of R_i is watched (models 2, 3)";
  parameter Real wStick = if frictionModel == 3 then 1.0 else 0.0 "1 where the mechanism starts stuck (model 3; models 1 and 2 start slipping, sgn = 0)";
  parameter Real wHold = 1.0 - wStick "1 where the velocities keep their residual at rest and their signs are not watched there (models 1 and 2)";
  parameter Real wRest = if frictionModel == 3 or mu > 0 then 1.0 else 0.0 "1 where the mechanism can come to rest against friction (every model with friction)";
  parameter Real jointTurn = 1e-3 "|k_i| below which a zero crossing of omega_i is taken as the joint's own reversal (k_i crossing zero) whatever sgn1 says";
  parameter Real baumgarte(unit = "1/s") = 20 "Rate of the constraint stabilisation; 0 integrates Phi_q qdd = gamma unmodified";
  // Initial configuration: at rest, theta1 from eq. (26), theta2 and theta5 from the constraints
  parameter Real x_B0(unit = "m") = 0.2329 "Initial position of slider B";
  parameter Real theta1_0(unit = "rad") = asin((x_B0 ^ 2 + r1 ^ 2 + f ^ 2 - r3 ^ 2) / (2 * r1 * sqrt(x_B0 ^ 2 + f ^ 2))) - asin(x_B0 / sqrt(x_B0 ^ 2 + f ^ 2)) "Initial lever angle, eq. (26)";
  parameter Real theta2_0(unit = "rad") = asin((f - r1 * sin(theta1_0)) / r3) "Initial angle of link A-B, from Phi1 = 0";
  parameter Real theta5_0(unit = "rad") = asin((h - r4 * sin(theta1_0 + phi)) / r5) "Initial angle of link D-C, from Phi2 = 0";

  Flange flange_B "Slider B (output slider)";
  Flange flange_C "Slider C (driven by the PMLSM mover)";

  Real theta1(unit = "rad", start = theta1_0, fixed = true) "Angle of the lever arm O-A";
  Real theta2(unit = "rad", start = theta2_0, fixed = true) "Angle of link A-B";
  Real theta5(unit = "rad", start = theta5_0, fixed = true) "Angle of link D-C";
  Real omega1(unit = "rad/s", start = 0.0, fixed = true) "Angular velocity of the lever";
  Real omega2(unit = "rad/s", start = 0.0, fixed = true) "Angular velocity of link A-B";
  Real omega5(unit = "rad/s", start = 0.0, fixed = true) "Angular velocity of link D-C";
  Real alpha1(unit = "rad/s2") "Angular acceleration of the lever";
  Real alpha2(unit = "rad/s2") "Angular acceleration of link A-B";
  Real alpha5(unit = "rad/s2") "Angular acceleration of link D-C";
  Real lambda1(unit = "N") "Lagrange multiplier of Phi1 (slider B guide)";
  Real lambda2(unit = "N") "Lagrange multiplier of Phi2 (slider C guide)";
  discrete Real sgn1(start = 0.0) "sgn(omega1), latched at its zero crossings";
  discrete Real sgn2(start = 0.0) "sgn(omega2), latched at its zero crossings";
  discrete Real sgn5(start = 0.0) "sgn(omega5), latched at its zero crossings";
  discrete Real want2(start = 0.0) "Sign omega2 took while the mechanism's direction gave joint theta2 the other one (a flip held back), else 0";
  discrete Real want5(start = 0.0) "Sign omega5 took while the mechanism's direction gave joint theta5 the other one (a flip held back), else 0";
  discrete Real stuck(start = wStick) "1 while the mechanism is at rest against friction (model 3 starts stuck, models 1 and 2 slipping)";
  discrete Real dir(start = 0.0) "Direction of omega1 since the last breakaway or first motion, 0 while stuck";
  discrete Real dStick(start = 1.0) "Direction a stuck mechanism would break away in (model 3): the sign of T_st, switched when -dStick T_st exceeds half the static capacity";
  Real R1(unit = "N.m") "Row theta1 of Q_f' lambda / (mu sgn1)";
  Real R2(unit = "N.m") "Row theta2 of Q_f' lambda / (mu sgn2)";
  Real R5(unit = "N.m") "Row theta5 of Q_f' lambda / (mu sgn5)";
  discrete Real sR1(start = 1.0) "sgn(R1), latched at its zero crossings (models 2, 3)";
  discrete Real sR2(start = 1.0) "sgn(R2), latched at its zero crossings (models 2, 3)";
  discrete Real sR5(start = 1.0) "sgn(R5), latched at its zero crossings (models 2, 3)";
  Real c1 "Factor of mu R1 in tau1_f: sgn1 (model 1), sgn1 |R1|/R1 while slipping, 0 while stuck";
  Real c2 "Factor of mu R2 in tau2_f";
  Real c5 "Factor of mu R5 in tau5_f";
  Real u_st "Free variable of the theta1 row: alpha1 while slipping, the holding torque T_st while stuck";
  Real T_st(unit = "N.m") "Holding (static friction) torque of all joints projected on theta1 while stuck (model 3), else 0";
  Real T_s(unit = "N.m") "Static friction capacity mu_s sum_i |domega_i/domega1| |R_i| (model 3)";
  Real k2 "Kinematic ratio omega2/omega1 = -r1 cos(theta1)/(r3 cos(theta2))";
  Real k5 "Kinematic ratio omega5/omega1 = -r4 cos(theta1 + phi)/(r5 cos(theta5))";
  Real T_j2(unit = "N.m") "Static friction at joint theta2 while stuck (model 3): muStatic dStick sgn(k2) |R2|, else 0";
  Real T_j5(unit = "N.m") "Static friction at joint theta5 while stuck (model 3): muStatic dStick sgn(k5) |R5|, else 0";

  // Consistency of the present friction mode (Painlevé): eq. (18) on the loop closures is linear
  // in (alpha1, lambda1, lambda2) with alpha_i = k_i alpha1 + ...; its matrix has the mass column
  // (mA1, mA2, mA5) and the constraint and friction columns. guardSlip is its determinant with the
  // mode's friction factors c_i over the one without friction: 1 without friction or while stuck,
  // and it reaches zero where the coupled joint frictions admit no consistent slip. The FMU fails
  // at an event after which it is not positive (a variable named guard*, see docs/fmu-export.md).
  Real mA1 "Coefficient of alpha1 in the generalized equation of theta1 on the loop closures";
  Real mA2 "... of theta2";
  Real mA5 "... of theta5";
  Real slipDet "Determinant of eq. (18) in (alpha1, lambda1, lambda2) with the friction of the present mode";
  Real slipDet0 "The same determinant without friction";
  Real guardSlip "no consistent friction mode of the joints (a Painleve-type case: the coupled frictions of joints theta1, theta2, theta5 with signs sgn1, sgn2, sgn5 make eq. (18) singular)" ;

  Real x_B(unit = "m") "Position of slider B";
  Real v_B(unit = "m/s") "Velocity of slider B";
  Real a_B(unit = "m/s2") "Acceleration of slider B";
  Real x_C(unit = "m") "Position of slider C";
  Real v_C(unit = "m/s") "Velocity of slider C";
  Real a_C(unit = "m/s2") "Acceleration of slider C";
  Real Phi1(unit = "m") "Constraint residual of slider B";
  Real Phi2(unit = "m") "Constraint residual of slider C";
  Real dPhi1(unit = "m/s") "Time derivative of Phi1";
  Real dPhi2(unit = "m/s") "Time derivative of Phi2";
  Real aAx(unit = "m/s2");
  Real aAy(unit = "m/s2");
  Real aDx(unit = "m/s2");
  Real aDy(unit = "m/s2");
  Real aG3x(unit = "m/s2") "Acceleration of the centre of link A-B";
  Real aG3y(unit = "m/s2");
  Real aG5x(unit = "m/s2") "Acceleration of the centre of link D-C";
  Real aG5y(unit = "m/s2");
  Real aBy(unit = "m/s2") "Vertical acceleration of point B (zero on the constraint)";
  Real aCy(unit = "m/s2") "Vertical acceleration of point C (zero on the constraint)";
  Real vG3x(unit = "m/s");
  Real vG3y(unit = "m/s");
  Real vG5x(unit = "m/s");
  Real vG5y(unit = "m/s");
  Real tau1_f(unit = "N.m") "Generalized friction force on theta1, row theta1 of Q_f' lambda";
  Real tau2_f(unit = "N.m") "Generalized friction force on theta2, row theta2 of Q_f' lambda";
  Real tau5_f(unit = "N.m") "Generalized friction force on theta5, row theta5 of Q_f' lambda";
  // Pin forces, from the Newton-Euler equations of sliders B, C and links 3, 5 with the solved
  // accelerations; the paper's friction torques act from ground on the bodies of their rows.
  Real F34x(unit = "N") "Force of link 3 on slider B at joint (3,4), x";
  Real F34y(unit = "N") "Force of link 3 on slider B at joint (3,4), y";
  Real F23x(unit = "N") "Force of the lever on link 3 at joint (2,3), x";
  Real F23y(unit = "N") "Force of the lever on link 3 at joint (2,3), y";
  Real F56x(unit = "N") "Force of link 5 on slider C at joint (5,6), x";
  Real F56y(unit = "N") "Force of link 5 on slider C at joint (5,6), y";
  Real F25x(unit = "N") "Force of the lever on link 5 at joint (2,5), x";
  Real F25y(unit = "N") "Force of the lever on link 5 at joint (2,5), y";
  Real F12x(unit = "N") "Force of the ground on the lever at joint (1,2), x";
  Real F12y(unit = "N") "Force of the ground on the lever at joint (1,2), y";
  Real N12(unit = "N") "Normal (pin) force at joint (1,2)";
  Real N23(unit = "N") "Normal (pin) force at joint (2,3)";
  Real N34(unit = "N") "Normal (pin) force at joint (3,4)";
  Real N25(unit = "N") "Normal (pin) force at joint (2,5)";
  Real N56(unit = "N") "Normal (pin) force at joint (5,6)";
  Real Ff12(unit = "N") "Friction force at joint (1,2), mu N12";
  Real Ff23(unit = "N") "Friction force at joint (2,3), mu N23";
  Real Ff34(unit = "N") "Friction force at joint (3,4), mu N34";
  Real Ff25(unit = "N") "Friction force at joint (2,5), mu N25";
  Real Ff56(unit = "N") "Friction force at joint (5,6), mu N56";
  Real P_in(unit = "W") "Power delivered at flange C (the thrust)";
  Real P_load(unit = "W") "Power delivered against the load at flange B";
  Real P_fric(unit = "W") "Power of the joint friction of eq. (17), q_dot' Q_f' lambda (signed)";
  Real E_in(unit = "J", start = 0.0, fixed = true) "Work done by the thrust";
  Real E_load(unit = "J", start = 0.0, fixed = true) "Work done against the external force F_E";
  Real E_fric(unit = "J", start = 0.0, fixed = true) "Energy taken by the joint friction of eq. (17) (signed)";
  Real E_mech(unit = "J") "Kinetic plus potential energy of the mechanism";
equation
  der(theta1) = omega1;
  der(theta2) = omega2;
  der(theta5) = omega5;
  der(omega1) = alpha1;
  der(omega2) = alpha2;
  der(omega5) = alpha5;

  // Friction signs of eq. (17), sgn(0) = 0 until the first crossing; under models 1 and 2 they
  // are not watched at rest (wHold), where the residual velocities are noise around zero
  when (1.0 - wHold * stuck) * omega1 > 0 then
    sgn1 = 1.0;
  elsewhen (1.0 - wHold * stuck) * omega1 < 0 then
    sgn1 = -1.0;
  end when;
  // A joint's velocity is k_i omega1 on the loop closures, so it reverses only with the lever
  // (omega1 crosses zero) or by the geometry (k_i crosses zero). A zero crossing of omega_i that
  // contradicts sgn(k_i) sgn1 where k_i is not near zero is the constraint's residual velocity
  // while omega1 creeps through zero, not a reversal: the latch is held (want_i records the sign
  // omega_i took) and follows when k_i sgn1 turns to agree with it. Otherwise a held-back sign
  // would switch the joint's friction the wrong way, which near rest reverses alpha_i and makes
  // the latch chatter without end.
  when (1.0 - wHold * stuck) * omega2 > 0 then
    sgn2 = if wRest < 0.5 or sgn1 * k2 >= 0 or abs(k2) < jointTurn then 1.0 else pre(sgn2);
    want2 = if wRest < 0.5 or sgn1 * k2 >= 0 or abs(k2) < jointTurn then 0.0 else 1.0;
  elsewhen (1.0 - wHold * stuck) * omega2 < 0 then
    sgn2 = if wRest < 0.5 or sgn1 * k2 <= 0 or abs(k2) < jointTurn then -1.0 else pre(sgn2);
    want2 = if wRest < 0.5 or sgn1 * k2 <= 0 or abs(k2) < jointTurn then 0.0 else -1.0;
  elsewhen want2 * sgn1 * k2 > 0 then
    sgn2 = want2;
    want2 = 0.0;
  end when;
  when (1.0 - wHold * stuck) * omega5 > 0 then
    sgn5 = if wRest < 0.5 or sgn1 * k5 >= 0 or abs(k5) < jointTurn then 1.0 else pre(sgn5);
    want5 = if wRest < 0.5 or sgn1 * k5 >= 0 or abs(k5) < jointTurn then 0.0 else 1.0;
  elsewhen (1.0 - wHold * stuck) * omega5 < 0 then
    sgn5 = if wRest < 0.5 or sgn1 * k5 <= 0 or abs(k5) < jointTurn then -1.0 else pre(sgn5);
    want5 = if wRest < 0.5 or sgn1 * k5 <= 0 or abs(k5) < jointTurn then 0.0 else -1.0;
  elsewhen want5 * sgn1 * k5 > 0 then
    sgn5 = want5;
    want5 = 0.0;
  end when;

  // Rest (every model): break away when the holding torque exceeds the static capacity in the
  // direction dStick (the factor time keeps the condition false at the start, so a load above
  // it breaks away at t = 0+), turning a residual velocity that points the other way; stick when
  // omega1 crosses zero against the direction of slip; models 1 and 2 start slipping with dir = 0,
  // and their first motion sets it
  when time * stuck * (dStick * T_st - T_s) > 0 then
    stuck = 0.0;
    dir = dStick;
    reinit(omega1, (if dStick * omega1 < 0 then -1.0 else 1.0) * omega1);
    reinit(omega2, (if dStick * omega1 < 0 then -1.0 else 1.0) * omega2);
    reinit(omega5, (if dStick * omega1 < 0 then -1.0 else 1.0) * omega5);
  elsewhen (1.0 - stuck) * (-dir * omega1) > 0 then
    stuck = 1.0;
    dir = 0.0;
    reinit(omega1, (1.0 - wStick) * omega1);
    reinit(omega2, (1.0 - wStick) * omega2);
    reinit(omega5, (1.0 - wStick) * omega5);
  elsewhen wRest * (1.0 - stuck) * (1.0 - abs(dir)) * omega1 > 0 then
    stuck = 0.0;
    dir = 1.0;
  elsewhen wRest * (1.0 - stuck) * (1.0 - abs(dir)) * omega1 < 0 then
    stuck = 0.0;
    dir = -1.0;
  end when;

  // The direction a stuck mechanism would break away in: switched with a margin of half the
  // static capacity, so that the switch (which moves the friction of joints theta2 and theta5
  // and with it lambda and T_s a little) cannot switch back at the same instant, and always
  // before the capacity in the other direction is reached
  when time * stuck * (-dStick * T_st - 0.5 * T_s) > 0 then
    dStick = sign(T_st);
  end when;

  // Signs of the rows R_i (models 2, 3); the factor time sets them at t = 0+ whatever the
  // start value, and wDiss = 0 keeps the indicators at zero under the paper's model
  when time * (wDiss + (1.0 - wDiss) * stuck) * R1 > 0 then
    sR1 = 1.0;
  elsewhen time * (wDiss + (1.0 - wDiss) * stuck) * R1 < 0 then
    sR1 = -1.0;
  end when;
  when time * (wDiss + (1.0 - wDiss) * stuck) * R2 > 0 then
    sR2 = 1.0;
  elsewhen time * (wDiss + (1.0 - wDiss) * stuck) * R2 < 0 then
    sR2 = -1.0;
  end when;
  when time * (wDiss + (1.0 - wDiss) * stuck) * R5 > 0 then
    sR5 = 1.0;
  elsewhen time * (wDiss + (1.0 - wDiss) * stuck) * R5 < 0 then
    sR5 = -1.0;
  end when;

  // Positions and velocities
  x_B = r1 * cos(theta1) + r3 * cos(theta2);
  x_C = r4 * cos(theta1 + phi) + r5 * cos(theta5);
  v_B = -r1 * sin(theta1) * omega1 - r3 * sin(theta2) * omega2;
  v_C = -r4 * sin(theta1 + phi) * omega1 - r5 * sin(theta5) * omega5;
  vG3x = -r1 * sin(theta1) * omega1 - 0.5 * r3 * sin(theta2) * omega2;
  vG3y = r1 * cos(theta1) * omega1 + 0.5 * r3 * cos(theta2) * omega2;
  vG5x = -r4 * sin(theta1 + phi) * omega1 - 0.5 * r5 * sin(theta5) * omega5;
  vG5y = r4 * cos(theta1 + phi) * omega1 + 0.5 * r5 * cos(theta5) * omega5;
  flange_B.s = x_B;
  flange_C.s = x_C;
  Phi1 = r1 * sin(theta1) + r3 * sin(theta2) - f;
  Phi2 = h - r4 * sin(theta1 + phi) - r5 * sin(theta5);
  dPhi1 = r1 * cos(theta1) * omega1 + r3 * cos(theta2) * omega2;
  dPhi2 = -r4 * cos(theta1 + phi) * omega1 - r5 * cos(theta5) * omega5;

  // Accelerations of the points, linear in alpha
  aAx = -r1 * (sin(theta1) * alpha1 + cos(theta1) * omega1 ^ 2);
  aAy = r1 * (cos(theta1) * alpha1 - sin(theta1) * omega1 ^ 2);
  aDx = -r4 * (sin(theta1 + phi) * alpha1 + cos(theta1 + phi) * omega1 ^ 2);
  aDy = r4 * (cos(theta1 + phi) * alpha1 - sin(theta1 + phi) * omega1 ^ 2);
  aG3x = aAx - 0.5 * r3 * (sin(theta2) * alpha2 + cos(theta2) * omega2 ^ 2);
  aG3y = aAy + 0.5 * r3 * (cos(theta2) * alpha2 - sin(theta2) * omega2 ^ 2);
  a_B = aAx - r3 * (sin(theta2) * alpha2 + cos(theta2) * omega2 ^ 2);
  aBy = aAy + r3 * (cos(theta2) * alpha2 - sin(theta2) * omega2 ^ 2);
  aG5x = aDx - 0.5 * r5 * (sin(theta5) * alpha5 + cos(theta5) * omega5 ^ 2);
  aG5y = aDy + 0.5 * r5 * (cos(theta5) * alpha5 - sin(theta5) * omega5 ^ 2);
  a_C = aDx - r5 * (sin(theta5) * alpha5 + cos(theta5) * omega5 ^ 2);
  aCy = aDy + r5 * (cos(theta5) * alpha5 - sin(theta5) * omega5 ^ 2);

  // Rows of Q_f' lambda, eq. (17), with the factor c_i of the friction model in place of sgn_i
  R1 = -r1 * sin(theta1) * lambda1 + r4 * sin(theta1 + phi) * lambda2;
  R2 = -r3 * sin(theta2) * lambda1;
  R5 = r5 * sin(theta5) * lambda2;
  c1 = if frictionModel == 1 then (1.0 - stuck) * sgn1 else (1.0 - stuck) * sgn1 * sR1;
  c2 = if frictionModel == 1 then (1.0 - stuck) * sgn2 else (1.0 - stuck) * sgn2 * sR2;
  c5 = if frictionModel == 1 then (1.0 - stuck) * sgn5 else (1.0 - stuck) * sgn5 * sR5;
  tau1_f = mu * c1 * (-r1 * sin(theta1) * lambda1 + r4 * sin(theta1 + phi) * lambda2) + T_st - k2 * T_j2 - k5 * T_j5;
  tau2_f = -mu * c2 * r3 * sin(theta2) * lambda1 + T_j2;
  tau5_f = mu * c5 * r5 * sin(theta5) * lambda2 + T_j5;
  k2 = -r1 * cos(theta1) / (r3 * cos(theta2));
  k5 = -r4 * cos(theta1 + phi) / (r5 * cos(theta5));
  T_j2 = stuck * muStatic * dStick * sign(k2) * sR2 * R2;
  T_j5 = stuck * muStatic * dStick * sign(k5) * sR5 * R5;
  // Sticking: alpha1 = u_st and T_st = 0 while slipping; while stuck T_st = u_st (the lever's
  // joint takes T_st - k2 T_j2 - k5 T_j5, so the three joints' friction projected on theta1,
  // tau1 + k2 tau2 + k5 tau5, is T_st) and
  // alpha1 = -stickDecay omega1 + stickCompliance T_st (the coefficient of u_st is never zero,
  // so the compiler may solve this equation for u_st in either state)
  alpha1 = ((1.0 - stuck) + stuck * stickCompliance) * u_st - stuck * stickDecay * omega1;
  T_st = stuck * u_st;
  T_s = muStatic * (abs(R1) + abs(k2) * abs(R2) + abs(k5) * abs(R5));

  // Consistency of the friction mode: the matrix of eq. (18) in (alpha1, lambda1, lambda2)
  mA1 = J2 + m3 * ((r1 * sin(theta1) + 0.5 * r3 * sin(theta2) * k2) * r1 * sin(theta1) + (r1 * cos(theta1) + 0.5 * r3 * cos(theta2) * k2) * r1 * cos(theta1))
    + m_B * (r1 * sin(theta1) + r3 * sin(theta2) * k2) * r1 * sin(theta1)
    + m5 * ((r4 * sin(theta1 + phi) + 0.5 * r5 * sin(theta5) * k5) * r4 * sin(theta1 + phi) + (r4 * cos(theta1 + phi) + 0.5 * r5 * cos(theta5) * k5) * r4 * cos(theta1 + phi))
    + m_C * (r4 * sin(theta1 + phi) + r5 * sin(theta5) * k5) * r4 * sin(theta1 + phi);
  mA2 = J3 * k2 + m3 * 0.5 * r3 * ((r1 * sin(theta1) + 0.5 * r3 * sin(theta2) * k2) * sin(theta2) + (r1 * cos(theta1) + 0.5 * r3 * cos(theta2) * k2) * cos(theta2))
    + m_B * (r1 * sin(theta1) + r3 * sin(theta2) * k2) * r3 * sin(theta2);
  mA5 = J5 * k5 + m5 * 0.5 * r5 * ((r4 * sin(theta1 + phi) + 0.5 * r5 * sin(theta5) * k5) * sin(theta5) + (r4 * cos(theta1 + phi) + 0.5 * r5 * cos(theta5) * k5) * cos(theta5))
    + m_C * (r4 * sin(theta1 + phi) + r5 * sin(theta5) * k5) * r5 * sin(theta5);
  slipDet = (mA1 * (r3 * cos(theta2) - mu * c2 * r3 * sin(theta2)) - (r1 * cos(theta1) - mu * c1 * r1 * sin(theta1)) * mA2) * (-r5 * cos(theta5) + mu * c5 * r5 * sin(theta5))
    - (-r4 * cos(theta1 + phi) + mu * c1 * r4 * sin(theta1 + phi)) * (r3 * cos(theta2) - mu * c2 * r3 * sin(theta2)) * mA5;
  slipDet0 = (mA1 * r3 * cos(theta2) - r1 * cos(theta1) * mA2) * (-r5 * cos(theta5)) + r4 * cos(theta1 + phi) * r3 * cos(theta2) * mA5;
  guardSlip = slipDet / slipDet0;

  // Eq. (18), generalized equation of theta1
  J2 * alpha1 + m3 * (-aG3x * r1 * sin(theta1) + aG3y * r1 * cos(theta1)) - m_B * a_B * r1 * sin(theta1)
    + m5 * (-aG5x * r4 * sin(theta1 + phi) + aG5y * r4 * cos(theta1 + phi)) - m_C * a_C * r4 * sin(theta1 + phi)
    + m3 * g * r1 * cos(theta1) + m5 * g * r4 * cos(theta1 + phi)
    - flange_B.f * (-r1 * sin(theta1)) - flange_C.f * (-r4 * sin(theta1 + phi))
    + r1 * cos(theta1) * lambda1 - r4 * cos(theta1 + phi) * lambda2 + tau1_f = 0;
  // ... of theta2
  J3 * alpha2 + m3 * 0.5 * r3 * (-aG3x * sin(theta2) + aG3y * cos(theta2)) - m_B * a_B * r3 * sin(theta2)
    + m3 * g * 0.5 * r3 * cos(theta2) - flange_B.f * (-r3 * sin(theta2))
    + r3 * cos(theta2) * lambda1 + tau2_f = 0;
  // ... of theta5
  J5 * alpha5 + m5 * 0.5 * r5 * (-aG5x * sin(theta5) + aG5y * cos(theta5)) - m_C * a_C * r5 * sin(theta5)
    + m5 * g * 0.5 * r5 * cos(theta5) - flange_C.f * (-r5 * sin(theta5))
    - r5 * cos(theta5) * lambda2 + tau5_f = 0;
  // Phi_q qdd = gamma, with Baumgarte stabilisation (Phi'' + 2 b Phi' + b^2 Phi = 0)
  aBy + 2 * baumgarte * dPhi1 + baumgarte ^ 2 * Phi1 = 0;
  -aCy + 2 * baumgarte * dPhi2 + baumgarte ^ 2 * Phi2 = 0;

  // Pin forces (Newton-Euler of sliders B, C and links 3, 5)
  F34x = m_B * a_B - flange_B.f;
  r3 * cos(theta2) * F34y = r3 * sin(theta2) * F34x - 0.5 * r3 * cos(theta2) * m3 * g - tau2_f - J3 * alpha2
    - 0.5 * r3 * m3 * (cos(theta2) * aG3y - sin(theta2) * aG3x);
  F23x = m3 * aG3x + F34x;
  F23y = m3 * aG3y + F34y + m3 * g;
  F56x = m_C * a_C - flange_C.f;
  r5 * cos(theta5) * F56y = r5 * sin(theta5) * F56x - 0.5 * r5 * cos(theta5) * m5 * g - tau5_f - J5 * alpha5
    - 0.5 * r5 * m5 * (cos(theta5) * aG5y - sin(theta5) * aG5x);
  F25x = m5 * aG5x + F56x;
  F25y = m5 * aG5y + F56y + m5 * g;
  F12x = F23x + F25x;
  F12y = F23y + F25y + m2 * g;
  N12 = sqrt(F12x ^ 2 + F12y ^ 2);
  N23 = sqrt(F23x ^ 2 + F23y ^ 2);
  N34 = sqrt(F34x ^ 2 + F34y ^ 2);
  N25 = sqrt(F25x ^ 2 + F25y ^ 2);
  N56 = sqrt(F56x ^ 2 + F56y ^ 2);
  Ff12 = mu * N12;
  Ff23 = mu * N23;
  Ff34 = mu * N34;
  Ff25 = mu * N25;
  Ff56 = mu * N56;

  // Energy bookkeeping: E_in = (E_mech - E_mech(0)) + E_fric + E_load
  P_in = flange_C.f * v_C;
  P_load = -flange_B.f * v_B;
  P_fric = omega1 * tau1_f + omega2 * tau2_f + omega5 * tau5_f;
  der(E_in) = P_in;
  der(E_load) = P_load;
  der(E_fric) = P_fric;
  E_mech = 0.5 * J2 * omega1 ^ 2 + 0.5 * m3 * (vG3x ^ 2 + vG3y ^ 2) + 0.5 * J3 * omega2 ^ 2 + 0.5 * m_B * v_B ^ 2
    + 0.5 * m5 * (vG5x ^ 2 + vG5y ^ 2) + 0.5 * J5 * omega5 ^ 2 + 0.5 * m_C * v_C ^ 2
    + m3 * g * (r1 * sin(theta1) + 0.5 * r3 * sin(theta2)) + m5 * g * (r4 * sin(theta1 + phi) + 0.5 * r5 * sin(theta5));
end ToggleMechanism;
