"""The physics the reference plant and the onboard sensor share: oil properties, kinematics, gear and bearing losses,
heat-transfer laws (seed equation numbers in comments). Pure functions of SI quantities; imports nothing from
``firmware_model.onboard``, ``firmware_model.service`` or ``tools``."""
