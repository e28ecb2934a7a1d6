/* The plant's physics steps in C: actuators, Magic Formula tyres and one MuJoCo step each.
 *
 * cosim_plant_advance(m, d, n, ...) does exactly what n calls of
 * cosim.plant.car.MujocoPlant.advance do in Python (without slip control, which keeps the
 * Python step): per step, the steering actuator's lag, rate limit and
 * Ackermann split into the two servos' commands, the drive torque with its power limit
 * and the brakes as implicit damping, drag and rolling resistance on the chassis,
 * mj_step1, the four tyres (the CasADi-generated function of cosim.plant.tyre_patches,
 * compiled into the same library), mj_step2 and the tyres' new loads; then the checks of
 * MujocoPlant._check; then, with traffic, the traffic cars' mocap poses of that step
 * (cosim.plant.traffic.Traffic.place, computed by Python for the n steps in `poses`).
 * Every expression is the Python one in the same order, so the same
 * IEEE operations give the same numbers (compiled without floating-point contraction).
 *
 * The state that outlives a step (steering, commands, the chassis velocity before the
 * step, the tyres' loads) lives in `s` (PS_* indices), owned by Python; constants in `c`
 * (PC_*) and `ic` (PI_*); the tyres' buffers are Python's numpy arrays.
 *
 * Returns n when every step was done; -2 - k when step k (0-based, the last one done)
 * ended with a MuJoCo warning or a non-finite or absurd state (the caller raises the
 * error); -1 when the tyres had more ground contacts than MAX_TYRE_CONTACTS or their
 * function failed.
 */

#include <math.h>
#include <mujoco/mujoco.h>

#ifndef PATCHES
#error "PATCHES must name the tyre function"
#endif

typedef long long int casadi_int;
int PATCHES(const double** arg, double** res, casadi_int* iw, double* w, int mem);

enum {
  PS_COMMAND, PS_ANGLE, PS_WHEEL_LEFT, PS_WHEEL_RIGHT, PS_RATE_LEFT, PS_RATE_RIGHT,
  PS_DRIVE, PS_BRAKE, PS_PREV_VX, PS_PREV_VY, PS_PREV_VZ, PS_LOAD0, PS_SIZE = PS_LOAD0 + 4
};
enum {
  PC_DT, PC_DECAY, PC_STEP_MAX, PC_MAX_STEER, PC_WHEELBASE, PC_FRONT_TRACK, PC_KV_KP,
  PC_I_KP, PC_MAX_POWER, PC_MIN_POWER_SPIN, PC_BRAKE_SCALE2, PC_BRAKE_SHARE0,
  PC_DRAG = PC_BRAKE_SHARE0 + 4, PC_ROLLING, PC_ROLLING_SPEED, PC_MAX_VEL2, PC_MAX_POS2,
  PC_FRICTION, PC_SIZE
};
enum {
  PI_SERVO_LEFT, PI_SERVO_RIGHT, PI_N_DRIVEN, PI_DRIVEN_DOF0, PI_DRIVE_ACT0 = PI_DRIVEN_DOF0 + 4,
  PI_SPIN_DOF0 = PI_DRIVE_ACT0 + 4, PI_LINVEL = PI_SPIN_DOF0 + 4, PI_CHASSIS,
  PI_WHEEL_BODY0, PI_TYRE_GEOM0 = PI_WHEEL_BODY0 + 4, PI_SIZE = PI_TYRE_GEOM0 + 4
};

#define N_WHEELS 4
#define CONTACT_SIZE 8
#define MAX_TYRE_CONTACTS 64

int cosim_plant_sizes(int* sizes) {
  sizes[0] = PS_SIZE;
  sizes[1] = PC_SIZE;
  sizes[2] = PI_SIZE;
  return 0;
}

static double min2(double a, double b) { return b < a ? b : a; } /* Python's min(a, b) */
static double max2(double a, double b) { return b > a ? b : a; } /* Python's max(a, b) */

static void steer(const double* c, const int* ic, double* s, mjData* d) {
  double limit = c[PC_MAX_STEER];
  double target = min2(max2(s[PS_COMMAND], -limit), limit);
  double lagged = target + (s[PS_ANGLE] - target) * c[PC_DECAY];
  double step = min2(max2(lagged - s[PS_ANGLE], -c[PC_STEP_MAX]), c[PC_STEP_MAX]);
  s[PS_ANGLE] += step;
  double tan_delta = tan(s[PS_ANGLE]);
  double wheelbase = c[PC_WHEELBASE];
  double lever = 0.5 * c[PC_FRONT_TRACK] * tan_delta;
  double left = atan2(wheelbase * tan_delta, wheelbase - lever);
  double right = atan2(wheelbase * tan_delta, wheelbase + lever);
  double dt = c[PC_DT];
  double rate_left = (left - s[PS_WHEEL_LEFT]) / dt, rate_right = (right - s[PS_WHEEL_RIGHT]) / dt;
  double kv_kp = c[PC_KV_KP], i_kp = c[PC_I_KP];
  d->ctrl[ic[PI_SERVO_LEFT]] =
      left + kv_kp * rate_left + i_kp * (rate_left - s[PS_RATE_LEFT]) / dt;
  d->ctrl[ic[PI_SERVO_RIGHT]] =
      right + kv_kp * rate_right + i_kp * (rate_right - s[PS_RATE_RIGHT]) / dt;
  s[PS_WHEEL_LEFT] = left;
  s[PS_WHEEL_RIGHT] = right;
  s[PS_RATE_LEFT] = rate_left;
  s[PS_RATE_RIGHT] = rate_right;
}

static void drive_and_brake(mjModel* m, const double* c, const int* ic, const double* s,
                            mjData* d, const double* qvel) {
  int n_driven = ic[PI_N_DRIVEN];
  double drive = s[PS_DRIVE];
  if (drive > 0.0) {
    double sum = 0.0;
    for (int i = 0; i < n_driven; i++) sum += fabs(qvel[ic[PI_DRIVEN_DOF0 + i]]);
    double spin = sum / n_driven;
    drive = min2(drive, c[PC_MAX_POWER] / max2(spin, c[PC_MIN_POWER_SPIN]));
  }
  double brake = s[PS_BRAKE];
  double per_wheel = drive / n_driven;
  for (int i = 0; i < n_driven; i++) d->ctrl[ic[PI_DRIVE_ACT0 + i]] = per_wheel;
  for (int i = 0; i < N_WHEELS; i++) {
    int dof = ic[PI_SPIN_DOF0 + i];
    double omega = qvel[dof];
    m->dof_damping[dof] =
        brake * c[PC_BRAKE_SHARE0 + i] / sqrt(omega * omega + c[PC_BRAKE_SCALE2]);
  }
}

static void resist(const double* c, const int* ic, mjData* d, const double* qvel) {
  double vx = qvel[ic[PI_LINVEL]], vy = qvel[ic[PI_LINVEL] + 1];
  double speed = sqrt(vx * vx + vy * vy);
  double* force = d->xfrc_applied + 6 * ic[PI_CHASSIS];
  if (speed > 1e-9) {
    double drag = c[PC_DRAG] * speed * fabs(speed);
    double rolling = c[PC_ROLLING] * tanh(speed / c[PC_ROLLING_SPEED]);
    double scale = (drag + rolling) / speed;
    force[0] = -scale * vx;
    force[1] = -scale * vy;
  } else {
    force[0] = 0.0;
    force[1] = 0.0;
  }
}

/* The wheel of a tyre geom (-1: not a tyre). */
static int wheel_of(const int* ic, int geom) {
  for (int w = 0; w < N_WHEELS; w++)
    if (ic[PI_TYRE_GEOM0 + w] == geom) return w;
  return -1;
}

/* MagicFormulaTyres.apply_forces; fills the tyre contacts' constraint rows. */
static int apply_tyres(const double* c, const int* ic, double* s, mjData* d, double* contact_buf,
                       double* state_buf, double* wrench, double* forces, double* new_state,
                       casadi_int* iw, double* w, int* efc_wheel, int* efc_address,
                       int* n_efc) {
  int contact_of_wheel[N_WHEELS] = {-1, -1, -1, -1};
  double sign_of_wheel[N_WHEELS] = {1.0, 1.0, 1.0, 1.0};
  double depth[N_WHEELS] = {INFINITY, INFINITY, INFINITY, INFINITY};
  int count = 0;
  for (int i = 0; i < d->ncon; i++) {
    const mjContact* contact = d->contact + i;
    double sign = 1.0;
    int wheel = wheel_of(ic, contact->geom[1]);
    if (wheel < 0) {
      sign = -1.0;
      wheel = wheel_of(ic, contact->geom[0]);
      if (wheel < 0) continue;
    }
    if (contact->efc_address >= 0) {
      if (count == MAX_TYRE_CONTACTS) return -1;
      efc_wheel[count] = wheel;
      efc_address[count] = contact->efc_address;
      count++;
    }
    if (contact->dist < depth[wheel]) {
      depth[wheel] = contact->dist;
      contact_of_wheel[wheel] = i;
      sign_of_wheel[wheel] = sign;
    }
  }
  *n_efc = count;
  for (int wheel = 0; wheel < N_WHEELS; wheel++) {
    double* out = contact_buf + CONTACT_SIZE * wheel;
    int index = contact_of_wheel[wheel];
    if (index < 0) {
      for (int j = 0; j < 7; j++) out[j] = 0.0;
    } else {
      const mjContact* contact = d->contact + index;
      double sign = sign_of_wheel[wheel];
      out[0] = 1.0;
      out[1] = contact->pos[0];
      out[2] = contact->pos[1];
      out[3] = contact->pos[2];
      out[4] = sign * contact->frame[0];
      out[5] = sign * contact->frame[1];
      out[6] = sign * contact->frame[2];
    }
    out[7] = s[PS_LOAD0 + wheel];
  }
  const double* arg[8] = {d->cvel, d->xpos, d->xipos, d->xmat, d->subtree_com, contact_buf,
                          state_buf, c + PC_FRICTION};
  double* res[3] = {wrench, forces, new_state};
  if (PATCHES(arg, res, iw, w, 0)) return -1;
  for (int wheel = 0; wheel < N_WHEELS; wheel++) {
    double* row = d->xfrc_applied + 6 * ic[PI_WHEEL_BODY0 + wheel];
    for (int j = 0; j < 6; j++) row[j] = wrench[6 * wheel + j];
  }
  for (int j = 0; j < 4 * N_WHEELS; j++) state_buf[j] = new_state[j];
  return 0;
}

static int healthy(const mjModel* m, const double* c, const mjData* d) {
  for (int i = 0; i < mjNWARNING; i++)
    if (d->warning[i].number) return 0;
  double velocity = 0.0, position = 0.0;
  for (int i = 0; i < m->nv; i++) velocity += d->qvel[i] * d->qvel[i];
  for (int i = 0; i < m->nq; i++) position += d->qpos[i] * d->qpos[i];
  return velocity < c[PC_MAX_VEL2] && position < c[PC_MAX_POS2];
}

/* After step k, the traffic cars' mocap poses: for car j (mocap slot slots[j]), position
 * (3) then quaternion (4) in row k of `poses` (7 numbers per car). */
static void place_traffic(mjData* d, const double* poses, const int* slots, int n_cars,
                          int k) {
  const double* row = poses + 7 * n_cars * k;
  for (int j = 0; j < n_cars; j++) {
    double* pos = d->mocap_pos + 3 * slots[j];
    double* quat = d->mocap_quat + 4 * slots[j];
    for (int i = 0; i < 3; i++) pos[i] = row[7 * j + i];
    for (int i = 0; i < 4; i++) quat[i] = row[7 * j + 3 + i];
  }
}

/* MujocoPlant._physics_step and MujocoPlant._check: mj_step1, the tyres, mj_step2, the
 * tyres' new loads into s; 0, -1 when the tyres failed, -2 when the state is not healthy. */
static int physics_step(mjModel* m, mjData* d, double* s, const double* c, const int* ic,
                        double* contact_buf, double* state_buf, double* wrench,
                        double* forces, double* new_state, casadi_int* iw, double* w) {
  int efc_wheel[MAX_TYRE_CONTACTS], efc_address[MAX_TYRE_CONTACTS];
  int n_efc = 0;
  mj_step1(m, d);
  if (apply_tyres(c, ic, s, d, contact_buf, state_buf, wrench, forces, new_state, iw, w,
                  efc_wheel, efc_address, &n_efc))
    return -1;
  mj_step2(m, d);
  double loads[N_WHEELS] = {0.0, 0.0, 0.0, 0.0};
  for (int i = 0; i < n_efc; i++) loads[efc_wheel[i]] += d->efc_force[efc_address[i]];
  for (int wheel = 0; wheel < N_WHEELS; wheel++) s[PS_LOAD0 + wheel] = loads[wheel];
  return healthy(m, c, d) ? 0 : -2;
}

int cosim_plant_advance(mjModel* m, mjData* d, int n, double* s, const double* c,
                        const int* ic, double* contact_buf, double* state_buf,
                        double* wrench, double* forces, double* new_state, casadi_int* iw,
                        double* w, const double* poses, const int* slots, int n_cars) {
  for (int k = 0; k < n; k++) {
    /* The velocities before the step, as advance() reads them (qvel.tolist()). */
    const double* qvel = d->qvel;
    double vx = qvel[ic[PI_LINVEL]], vy = qvel[ic[PI_LINVEL] + 1], vz = qvel[ic[PI_LINVEL] + 2];
    steer(c, ic, s, d);
    drive_and_brake(m, c, ic, s, d, qvel);
    resist(c, ic, d, qvel);
    s[PS_PREV_VX] = vx;
    s[PS_PREV_VY] = vy;
    s[PS_PREV_VZ] = vz;
    int status = physics_step(m, d, s, c, ic, contact_buf, state_buf, wrench, forces,
                              new_state, iw, w);
    if (status) return status == -1 ? -1 : -2 - k;
    if (n_cars) place_traffic(d, poses, slots, n_cars, k);
  }
  return n;
}

/* n of MujocoPlant._settle's steps: MujocoPlant._physics_step (mj_step1, the tyres,
 * mj_step2, the tyres' new loads) and its checks, no actuator and no resistance; the same
 * returns as cosim_plant_advance's. */
int cosim_plant_settle(mjModel* m, mjData* d, int n, double* s, const double* c,
                       const int* ic, double* contact_buf, double* state_buf, double* wrench,
                       double* forces, double* new_state, casadi_int* iw, double* w) {
  for (int k = 0; k < n; k++) {
    int status = physics_step(m, d, s, c, ic, contact_buf, state_buf, wrench, forces,
                              new_state, iw, w);
    if (status) return status == -1 ? -1 : -2 - k;
  }
  return n;
}

/* MujocoPlant.state's numbers (cosim/plant/car.py) from the data after a step, expression by
 * expression: position, roll, pitch and yaw of the chassis quaternion (euler_zyx), the
 * world velocity and the acceleration over the last step (from the velocity before it,
 * pv) turned into the chassis frame, the yaw rate, the mean front road-wheel angle and the
 * wheels' spin rates. `at`: the free joint's qpos and dof addresses, the two steering
 * joints' qpos addresses, the four spin dofs. out: x, y, z, roll, pitch, yaw, vx, vy,
 * yaw_rate, ax, ay, steer, then the four spin rates. */
int cosim_plant_state(const mjData* d, const int* at, double pvx, double pvy, double pvz,
                      double inv_dt, double* out) {
  const double* q = d->qpos + at[0];
  const double* v = d->qvel + at[1];
  double qw = q[3], qx = q[4], qy = q[5], qz = q[6];
  double roll = atan2(2.0 * (qw * qx + qy * qz), 1.0 - 2.0 * (qx * qx + qy * qy));
  double sin_pitch = 2.0 * (qw * qy - qz * qx);
  double pitch = asin(min2(max2(sin_pitch, -1.0), 1.0));
  double yaw = atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz));
  double xx = 1.0 - 2.0 * (qy * qy + qz * qz), xy = 2.0 * (qx * qy + qw * qz),
         xz = 2.0 * (qx * qz - qw * qy);
  double yx = 2.0 * (qx * qy - qw * qz), yy = 1.0 - 2.0 * (qx * qx + qz * qz),
         yz = 2.0 * (qy * qz + qw * qx);
  double vwx = v[0], vwy = v[1], vwz = v[2];
  double awx = (vwx - pvx) * inv_dt, awy = (vwy - pvy) * inv_dt, awz = (vwz - pvz) * inv_dt;
  out[0] = q[0];
  out[1] = q[1];
  out[2] = q[2];
  out[3] = roll;
  out[4] = pitch;
  out[5] = yaw;
  out[6] = xx * vwx + xy * vwy + xz * vwz;
  out[7] = yx * vwx + yy * vwy + yz * vwz;
  out[8] = v[5];
  out[9] = xx * awx + xy * awy + xz * awz;
  out[10] = yx * awx + yy * awy + yz * awz;
  out[11] = 0.5 * (d->qpos[at[2]] + d->qpos[at[3]]);
  for (int wheel = 0; wheel < N_WHEELS; wheel++) out[12 + wheel] = d->qvel[at[4 + wheel]];
  return 0;
}
