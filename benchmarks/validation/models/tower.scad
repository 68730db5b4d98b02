// hollow square tower with a slot: small layers, short runs, retractions
difference() {
  cube([9, 9, 20]);
  translate([1.6, 1.6, 1]) cube([5.8, 5.8, 20]);
  translate([3.5, -1, 8]) cube([2, 3, 6]);
}
