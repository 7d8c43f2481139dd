"""The CAN service with the onboard sensor, built from a project configuration: what `gearbox-vsensor run`, the log
replay, the diagnosis of CAN logs and the tests start from."""

from __future__ import annotations

from firmware_model.service.core import SensorService
from firmware_model.service.options import ServiceOptions


def build_service(
    config_path=None,
    *,
    record: bool = False,
    emit_frames: bool = True,
    sensor_options=None,
    logger=None,
    **overrides,
) -> SensorService:
    """Config (a TOML path, None: the defaults) -> SensorService with the onboard VirtualSensor.

    ``sensor_options``: VirtualSensor options (oil_mode, initial_temp_c ...); ``logger``: where the service logs
    (None: its module's); ``overrides``: ServiceOptions fields.
    """
    from firmware_model.config import load_config
    from firmware_model.onboard.sensor import VirtualSensor

    cfg = load_config(config_path)
    sensor = VirtualSensor(cfg.load_params(), config=cfg, **(sensor_options or {}))
    return SensorService(
        sensor, ServiceOptions.from_config(cfg, **overrides), record=record, emit_frames=emit_frames, logger=logger
    )
