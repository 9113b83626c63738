import numpy as np

from bench.dut import MODE_DOPPLER, NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE, SOLUTION_VALID, Estimator, EstimatorOutput

R = 6_378_137.0  # m: a sphere is enough for a few kilometres


class GyroDoppler(Estimator):
    """Heading from the vertical gyro, speed from the Doppler radar, position integrated."""

    def configure(self, config):
        lat, lon, self.h = config["initial_position"]  # deg, deg, m: a surveyed start point
        self.lat, self.lon = np.radians(lat), np.radians(lon)
        self.heading = np.radians(config["initial_heading"])  # deg, clockwise from north
        self.speed, self.t_ns = 0.0, 0

    def step(self, inputs):
        d = inputs.doppler  # every field, zero-length when no DOPPLER frame came this step
        if np.any(d["valid"] == 1):
            self.speed = float(d["speed"][d["valid"] == 1][-1])
        imu = inputs.imu
        if len(imu) == 0:
            return EstimatorOutput()
        t = imu["t_ns"]
        dt = np.diff(t, prepend=self.t_ns) * 1e-9
        heading = self.heading - np.cumsum(imu["dtheta"][:, 2])  # body z is up: heading turns clockwise
        ve, vn = self.speed * np.sin(heading), self.speed * np.cos(heading)
        lat = self.lat + np.cumsum(vn * dt) / R
        lon = self.lon + np.cumsum(ve * dt) / (R * np.cos(lat))
        self.t_ns, self.heading, self.lat, self.lon = int(t[-1]), heading[-1], lat[-1], lon[-1]
        out = t % 10_000_000 == 0  # epochs at 100 Hz, each from the IMU frame of its time
        sol = np.zeros(out.sum(), NAV_SOLUTION_DTYPE)  # rx_ns and epoch: the bench fills them
        sol["t_ns"], sol["lat"], sol["lon"], sol["h"] = t[out], lat[out], lon[out], self.h
        sol["vel_n"][:, 0], sol["vel_n"][:, 1] = ve[out], vn[out]
        sol["heading"] = np.mod(heading[out], 2 * np.pi)
        sol["mode"], sol["valid"] = MODE_DOPPLER, SOLUTION_VALID
        q = np.zeros(len(sol), NAV_QUALITY_DTYPE)
        q["t_ns"], q["sigma_pos"], q["sigma_vel"], q["sigma_att"] = sol["t_ns"], 5.0, 0.2, 1e-3
        return EstimatorOutput(sol, q)
