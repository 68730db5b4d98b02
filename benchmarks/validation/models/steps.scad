// stepped pyramid: four square steps 32, 24, 16, 8 mm wide, each 2 mm high (top surfaces)
for (k = [0:3]) translate([-(16 - 4 * k), -(16 - 4 * k), 2 * k])
  cube([32 - 8 * k, 32 - 8 * k, 2]);
