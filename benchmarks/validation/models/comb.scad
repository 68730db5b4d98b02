// comb: nine 0.9 mm fins, 14 mm long, 8 mm tall, 3 mm apart, on a 2 mm spine
union() {
  translate([-14, -1, 0]) cube([28, 2, 8]);
  for (i = [0:8]) translate([-12.45 + 3 * i, 1, 0]) cube([0.9, 14, 8]);
}
