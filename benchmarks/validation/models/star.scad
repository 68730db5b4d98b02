// eight-pointed star prism: sharp inner and outer corners every few millimetres
linear_extrude(height = 6)
  polygon([for (i = [0:15]) let(r = (i % 2 == 0) ? 16 : 7, a = i * 360 / 16)
           [r * cos(a), r * sin(a)]]);
