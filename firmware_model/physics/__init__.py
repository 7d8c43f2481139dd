"""The physics the reference plant and the onboard sensor share, each equation once: oil properties (oil),
kinematics, gearbox geometry (geometry), gear and bearing losses (losses, gearbox_losses), heat-transfer laws
(heat_transfer), the oil cooler (cooler), the loss-to-heat lag (heat_lag) and the network's conductance matrix
(conductance_matrix); seed equation numbers in comments. Pure functions of SI quantities; imports nothing from
``firmware_model.network``, ``firmware_model.onboard``, ``firmware_model.service`` or ``tools``."""
