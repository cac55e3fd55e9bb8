//! WGS84 geodesy: geodetic <-> ECEF <-> local east-north-up, exact to well below a millimetre
//! over the kilometres a mission spans (no flat-earth approximation).
