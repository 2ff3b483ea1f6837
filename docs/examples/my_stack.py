"""An example controller: keeps the speed limit (braking for a lower one ahead) and its
distance to the car ahead, stops at red and yellow lights and once at each stop sign."""


def control(obs: dict) -> dict:
    speed, dt = obs["speed"], obs["step_length"]
    accel = min(2.0, obs["speed_limit"] - speed)           # towards the speed limit
    ahead = obs["next_speed_limit"]                        # brake for a lower limit ahead
    if ahead and ahead["limit"] < speed:
        accel = min(accel, (ahead["limit"] ** 2 - speed**2) / max(2 * ahead["distance"], 1.0))
    leader = obs["leader"]                                 # keep 2 s and 5 m to the car ahead
    if leader is not None:
        accel = min(accel, (leader["gap"] - 5.0 - 2.0 * speed) / 2.0)
    lines = []                                             # stop lines to halt at
    if obs["next_signal"] and obs["next_signal"]["state"] in "rRyu":
        lines.append(obs["next_signal"]["distance"] - 2.0)
    if obs["next_stop"] and not obs["next_stop"]["stopped"]:
        lines.append(obs["next_stop"]["distance"] - 0.5)
    for d in lines:                                        # fastest speed that still halts
        halt = -3.0 * dt + (9.0 * dt * dt + 6.0 * max(d, 0.0)) ** 0.5  # there at 3 m/s²
        accel = min(accel, (halt - speed) / dt)
    return {"acceleration": max(-6.0, accel)}
